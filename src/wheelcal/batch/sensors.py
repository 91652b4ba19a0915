"""The batch's deliverable per sensor: ``sensors/<sensor_id>.calibration.json``.

For every ``sensor_id`` with at least one calibrated session, pool the
sessions (:func:`wheelcal.closedloop.pooling.pool_sessions`) — with the joint
sensor fit of the closure when it ran and determines every parameter — and
write the pooled calibration atomically.  The report opens with these.
"""

from __future__ import annotations

import hashlib
import re
from collections import defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from wheelcal.calibration import (
    joint_estimate,
    read_only_document,
    sensor_calibration_dict,
    sensor_calibration_text,
    session_estimate,
    write_sensor_calibration,
)
from wheelcal.closedloop import pool_sessions
from wheelcal.io import MARK_KEY

SENSORS_FOLDER = "sensors"
STALE_SUFFIX = ".calibration.stale.json"


@dataclass(frozen=True, eq=False)
class SensorDeliverable:
    """One sensor's pooled calibration: where it was written, and its dictionary."""

    sensor_id: str
    path: Path
    doc: dict

    def summary(self) -> dict:
        """The ``report.json`` entry (additive key ``sensors``)."""
        return {
            "sensor_id": self.sensor_id,
            "file": str(self.path),
            "method": self.doc["pooling"]["method"],
            "sessions": self.doc["pooling"]["sessions"],
            "sensor": self.doc["sensor"],
            "correction": self.doc["correction"],
            "systematic": {k: v for k, v in self.doc["systematic"].items() if k != "note"},
            "warnings": self.doc["fit"]["warnings"],
            **({"allan": self.doc["fit"]["allan"]} if self.doc["fit"].get("allan") else {}),
        }


def sensor_file_stem(sensor_id: str) -> str:
    """A file name for a sensor id: the id itself when it is safe, else a safe, unique form."""
    if not sensor_id:
        return "unnamed"
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", sensor_id).strip(".") or "sensor"
    if safe == sensor_id:
        return safe
    return f"{safe}-{hashlib.sha256(sensor_id.encode()).hexdigest()[:8]}"


def write_sensor_calibrations(
    out_dir: Path,
    calibrations: Sequence[Mapping],
    calibration_paths: Mapping[str, str] | None = None,
    closure: Mapping | None = None,
    durable: bool = False,
    stage=None,
    mark: Mapping | None = None,
) -> list[SensorDeliverable]:
    """Pool and write one calibration per sensor; returns them sorted by sensor id.

    A sensor file of an earlier run whose sensor has no calibrated session now
    is renamed ``<stem>.calibration.stale.json``: nobody should apply it thinking
    it is this batch's.  With ``stage`` (:class:`~wheelcal.io.atomic.StagedOutputs`)
    the files and the renames wait for the stage's install; ``mark`` is stored
    as each file's ``wheelcal_output`` (:mod:`wheelcal.io.ownership`).
    """
    by_sensor: dict[str, list[Mapping]] = defaultdict(list)
    for cal in calibrations:
        source = read_only_document(cal).get("source", {})
        by_sensor[str(source.get("sensor_id") or "")].append(cal)
    fits = {
        s.get("sensor_id", ""): s.get("sensor_fit")
        for s in (closure or {}).get("sensors", [])
        if s.get("sensor_fit")
    }
    out = []
    for sensor_id, members in sorted(by_sensor.items()):
        joint = joint_estimate(fits[sensor_id]) if sensor_id in fits else None
        pooled = pool_sessions([session_estimate(c) for c in members], joint)
        doc = sensor_calibration_dict(sensor_id, pooled, members, calibration_paths)
        if mark is not None:
            doc[MARK_KEY] = dict(mark)
        path = Path(out_dir) / SENSORS_FOLDER / f"{sensor_file_stem(sensor_id)}.calibration.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        if stage is not None:
            stage.write_text(path, sensor_calibration_text(doc))
        else:
            write_sensor_calibration(path, doc, durable=durable)
        out.append(SensorDeliverable(sensor_id, path, doc))
    written = {d.path.name for d in out}
    for old in sorted((Path(out_dir) / SENSORS_FOLDER).glob("*.calibration.json")):
        if old.name not in written:
            new = old.with_name(old.name.replace(".calibration.json", STALE_SUFFIX))
            if stage is not None:
                stage.move(old, new)
            else:
                old.replace(new)
    return out
