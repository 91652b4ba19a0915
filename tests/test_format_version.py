"""A calibration document carries its type and format version (``format``), and
``Calibration.from_json`` refuses a version it does not read, naming the file — for
both kinds: a session's (``wheelcal.calibration/1``) and a sensor's
(``wheelcal.sensor_calibration/1``)."""

import json

import pytest

from wheelcal.calibration.document import Calibration
from wheelcal.calibration.session_json import (
    FORMAT,
    SENSOR_CALIBRATION_FORMAT,
    CalibrationFileError,
    write_calibration,
)
from wheelcal.estimate.joint import JointFit
from wheelcal.session.fit import session_of_fit

#: The smallest usable sensor document (the keys export and apply read).
SENSOR_DOCUMENT = {
    "format": SENSOR_CALIBRATION_FORMAT,
    "sensor_id": "imu",
    "sensor": {"gain": [1.0, 1.0, 1.0], "offset_mps2": [0.0, 0.0, 0.0], "undetermined": []},
    "correction": {
        "bias_mps2": [0.1, 0.2, 0.3],
        "matrix": [[1.01, 0.0, 0.0], [0.0, 0.99, 0.0], [0.0, 0.0, 1.02]],
    },
}


@pytest.fixture(scope="module")
def session_document(table1_session, tmp_path_factory):
    recording = table1_session.recording
    session = session_of_fit(JointFit().fit(recording), recording)
    path = write_calibration(tmp_path_factory.mktemp("v") / "s.calibration.json", session)
    return json.loads(path.read_text(encoding="utf-8"))


def _write(path, document):
    path.write_text(json.dumps(document, indent=2), encoding="utf-8")
    return path


def test_the_formats_are_type_and_version():
    assert FORMAT == "wheelcal.calibration/1"
    assert SENSOR_CALIBRATION_FORMAT == "wheelcal.sensor_calibration/1"


@pytest.mark.parametrize("kind", ["session", "sensor"])
def test_this_version_round_trips(kind, session_document, tmp_path):
    document = session_document if kind == "session" else SENSOR_DOCUMENT
    cal = Calibration.from_json(_write(tmp_path / "c.calibration.json", document))
    assert cal.kind == kind
    again = Calibration.from_json(cal.to_json(tmp_path / "again.calibration.json", durable=False))
    assert again.to_dict() == cal.to_dict() == document


@pytest.mark.parametrize("kind", ["session", "sensor"])
@pytest.mark.parametrize("version", ["2", "0", "1.1"])
def test_another_version_is_refused_naming_the_file(kind, version, session_document, tmp_path):
    document = dict(session_document if kind == "session" else SENSOR_DOCUMENT)
    tag = FORMAT if kind == "session" else SENSOR_CALIBRATION_FORMAT
    document["format"] = f"{tag.rpartition('/')[0]}/{version}"
    path = _write(tmp_path / f"newer-{kind}.calibration.json", document)
    with pytest.raises(CalibrationFileError) as refused:
        Calibration.from_json(path)
    message = str(refused.value)
    assert message.startswith(f"{path}: ")
    assert f"format version '{version}'" in message and f"reads version 1 ({tag})" in message
    with pytest.raises(CalibrationFileError, match="format version"):
        Calibration.from_document(document, path)


@pytest.mark.parametrize("tag", [None, "", "imucal/1", "wheelcal.diagnosis/1", 1])
def test_an_unknown_type_is_refused_naming_the_file(tag, tmp_path):
    document = dict(SENSOR_DOCUMENT)
    if tag is None:
        del document["format"]
    else:
        document["format"] = tag
    path = _write(tmp_path / "other.json", document)
    with pytest.raises(CalibrationFileError, match=r"format tag missing or different") as refused:
        Calibration.from_json(path)
    assert str(refused.value).startswith(f"{path}: not a ")
