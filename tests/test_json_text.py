"""The indented JSON writer against json.dumps(..., indent=2, allow_nan=False), byte for byte."""

import json

import numpy as np
import pytest

from wheelcal.calibration.session_json import calibration_dict
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.io.json_text import dumps_indented


def _random_value(rng, depth=0):
    kind = int(rng.integers(10 if depth < 4 else 6))
    if kind == 0:
        return float(rng.normal() * 10.0 ** rng.integers(-320, 309))
    if kind == 1:
        return int(rng.integers(-(2**62), 2**62)) * int(rng.choice([1, 10**30]))
    if kind == 2:
        return str(rng.choice(["", "a", 'quote " and \\ back', "tab\t\nline", "Ω ϑ₀ °/s", "\x00"]))
    if kind == 3:
        return [None, True, False][int(rng.integers(3))]
    if kind == 4:
        return float(rng.choice([0.0, -0.0, 1e-300, 5e-324, 1.7976931348623157e308, 0.1]))
    if kind == 5:
        return np.float64(rng.normal())  # a float subclass: json.dumps writes its float repr
    if kind == 6:  # a vector of plain floats, ints or strings (the one-join path)
        if rng.random() < 0.3:
            return [int(v) for v in rng.integers(-9, 9, int(rng.integers(1, 4)))] + ["s", 0.5]
        return [float(v) for v in rng.normal(size=int(rng.integers(0, 6)))]
    if kind == 7:
        items = [_random_value(rng, depth + 1) for _ in range(int(rng.integers(0, 4)))]
        return tuple(items) if rng.random() < 0.2 else items
    keys = ["a", "format", "ϑ", 'k"q', "", "x y"]
    return {
        str(rng.choice(keys)) + str(i): _random_value(rng, depth + 1)
        for i in range(int(rng.integers(0, 5)))
    }


def _outcome(dumps, doc):
    """The text, or the refusal's type and words."""
    try:
        return dumps(doc)
    except (TypeError, ValueError) as exc:
        return type(exc), str(exc)


def test_random_documents_are_json_dumps_byte_for_byte():
    rng = np.random.default_rng(21)
    for _ in range(2000):
        doc = _random_value(rng)
        want = _outcome(lambda d: json.dumps(d, indent=2, allow_nan=False), doc)
        assert _outcome(dumps_indented, doc) == want


def test_a_calibration_is_json_dumps_byte_for_byte(table1_session):
    doc = calibration_dict(JointFit().fit(table1_session.recording))
    text = dumps_indented(doc)
    assert text == json.dumps(doc, indent=2, allow_nan=False)
    assert text.count("\n") > 100  # the covariance rows took the vector path


@pytest.mark.parametrize(
    "doc",
    [
        {1: 2.0},  # a number as key: json.dumps writes "1"
        {None: [1.0], True: "x"},
        [1.0, float("nan")],
        {"x": [float("inf")]},
        {"x": float("-inf")},
        [np.int64(3)],  # json.dumps refuses it (TypeError)
        {"x": {1, 2}},
    ],
)
def test_what_is_not_plain_json_is_left_to_json_dumps(doc):
    try:
        want = json.dumps(doc, indent=2, allow_nan=False)
    except (TypeError, ValueError) as exc:
        with pytest.raises(type(exc)) as caught:
            dumps_indented(doc)
        assert str(caught.value) == str(exc)
    else:
        assert dumps_indented(doc) == want


def test_a_cycle_is_refused_as_json_dumps_refuses_it():
    doc = []
    doc.append(doc)
    with pytest.raises(ValueError, match="Circular reference"):
        dumps_indented(doc)
