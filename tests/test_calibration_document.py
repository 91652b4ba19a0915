"""Reading calibration documents once: the freeze/thaw shortcuts and ``from_document``."""

import json
from collections import OrderedDict
from types import MappingProxyType

import numpy as np

from wheelcal.calibration import document as calibration_module
from wheelcal.calibration.document import Calibration
from wheelcal.calibration.session_json import write_calibration
from wheelcal.estimate.joint.fit import JointFit


def _frozen_plain(value):
    if isinstance(value, dict):
        return MappingProxyType({k: _frozen_plain(v) for k, v in value.items()})
    if isinstance(value, list):
        return tuple(_frozen_plain(v) for v in value)
    return value


def _thawed_plain(value):
    if isinstance(value, MappingProxyType | dict):
        return {k: _thawed_plain(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [_thawed_plain(v) for v in value]
    return value


def _same(a, b) -> bool:
    """Equal, and of the same container types all the way down."""
    if type(a) is not type(b):
        return False
    if isinstance(a, MappingProxyType | dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return a == b or (a != a and b != b)


def _random(rng, depth=0):
    kind = int(rng.integers(6 if depth < 4 else 3))
    if kind == 0:
        return float(rng.normal())
    if kind == 1:
        return str(rng.integers(9))
    if kind == 2:
        return [None, True, 3][int(rng.integers(3))]
    if kind == 3:
        return [float(v) for v in rng.normal(size=int(rng.integers(0, 4)))]
    if kind == 4:
        return [_random(rng, depth + 1) for _ in range(int(rng.integers(0, 4)))]
    items = {f"k{i}": _random(rng, depth + 1) for i in range(int(rng.integers(0, 4)))}
    return OrderedDict(items) if rng.random() < 0.1 else items  # a dict subclass freezes too


def test_freeze_and_thaw_are_the_plain_recursions():
    rng = np.random.default_rng(31)
    for _ in range(2000):
        doc = _random(rng)
        frozen = calibration_module._frozen(doc)
        assert _same(frozen, _frozen_plain(doc))
        assert _same(calibration_module._thawed(frozen), _thawed_plain(frozen))


def test_from_document_is_from_json(table1_session, tmp_path):
    path = write_calibration(
        tmp_path / "s.calibration.json", JointFit().fit(table1_session.recording)
    )
    document = json.loads(path.read_text(encoding="utf-8"))
    read = Calibration.from_json(path)
    given = Calibration.from_document(document, path)
    assert _same(given.document, read.document)
    assert _same(given.to_dict(), read.to_dict())
    assert _same(read.to_dict(), document)
