"""``json.dumps(value, indent=2, allow_nan=False)``, the same text, several times faster.

The calibration JSON is written indented (the contract's files are read by
people too), and :func:`json.dumps` with an indent runs the pure-Python
encoder: a generator per container and per value, ~2 ms for a calibration
whose covariance matrix puts ~400 numbers on lines of their own.  This
encoder builds the same text directly: a list of plain floats, ints and
strings (a covariance row, a vector, names) is one ``join`` of their texts
(``float.__repr__``, ``int.__repr__``), strings go through
the C ``encode_basestring_ascii`` that :mod:`json` itself uses, and the
layout is :mod:`json`'s with ``indent`` and its separators ``","`` and
``": "``.  Anything outside plain JSON types (a non-string key, a numpy
scalar, a non-finite float, a cycle) is handed to :func:`json.dumps`, which
then writes or refuses it exactly as before.
"""

from __future__ import annotations

import json
import math
from json.encoder import encode_basestring_ascii
from types import MappingProxyType

import numpy as np

__all__ = ["dumps_indented", "json_safe"]


def json_safe(value):
    """``value`` with every non-finite float (NaN, ±∞) made None, through lists and mappings.

    JSON has no NaN: a report built from sessions with undetermined (null) values
    must still be written, with those values null (numpy scalars become plain).
    """
    if isinstance(value, (dict, MappingProxyType)):  # a dict, or a read-only view of one
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


class _NotPlain(Exception):
    """A value this encoder leaves to :func:`json.dumps`."""


def dumps_indented(value, indent: int = 2) -> str:
    """The text of ``json.dumps(value, indent=indent, allow_nan=False)``, byte for byte."""
    parts: list[str] = []
    try:
        _encode(value, parts, "\n", " " * indent)
    except (_NotPlain, RecursionError):
        return json.dumps(value, indent=indent, allow_nan=False)
    return "".join(parts)


def _float(value: float) -> str:
    text = float.__repr__(value)
    if "n" in text:  # "nan", "inf": refused (allow_nan=False) in json.dumps' words
        raise _NotPlain
    return text


#: Exact types whose text needs no recursion (bool is no int here: type(True) is bool).
_LEAVES = {
    float: _float,
    int: int.__repr__,
    str: encode_basestring_ascii,
    type(None): lambda _: "null",
}


def _encode(value, out: list[str], newline: str, step: str) -> None:
    """Append the text of ``value``; ``newline``: a line break and the indent of its line."""
    # the order of json.encoder._iterencode: str, None, True, False, int, float, list, dict
    if isinstance(value, str):
        out.append(encode_basestring_ascii(value))
    elif value is None:
        out.append("null")
    elif value is True:
        out.append("true")
    elif value is False:
        out.append("false")
    elif isinstance(value, int):
        out.append(int.__repr__(value))
    elif isinstance(value, float):
        out.append(_float(value))
    elif isinstance(value, (list, tuple)):
        if not value:
            out.append("[]")
            return
        inner = newline + step
        if all(type(item) is float for item in value):  # a vector, a matrix row
            text = ("," + inner).join(map(float.__repr__, value))
            if "n" in text:  # "nan", "inf"
                raise _NotPlain
            out.append("[" + inner + text + newline + "]")
            return
        try:  # numbers, strings and null only (names, a row with nulls): one join
            texts = [_LEAVES[type(item)](item) for item in value]
        except KeyError:
            pass
        else:
            out.append("[" + inner + ("," + inner).join(texts) + newline + "]")
            return
        out.append("[" + inner)
        for i, item in enumerate(value):
            if i:
                out.append("," + inner)
            _encode(item, out, inner, step)
        out.append(newline + "]")
    elif isinstance(value, dict):
        if not value:
            out.append("{}")
            return
        inner = newline + step
        out.append("{" + inner)
        for i, (key, item) in enumerate(value.items()):
            if not isinstance(key, str):
                raise _NotPlain  # json.dumps turns numbers, booleans and None into keys
            head = ("," + inner if i else "") + encode_basestring_ascii(key) + ": "
            leaf = _LEAVES.get(type(item))
            if leaf is not None:
                out.append(head + leaf(item))
            else:
                out.append(head)
                _encode(item, out, inner, step)
        out.append(newline + "}")
    else:
        raise _NotPlain
