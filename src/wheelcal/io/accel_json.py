"""``wheelcal.AccelBatch`` JSON messages: schema, encoding and fast decoding.

The contract's second input format (schema encoding ``jsonschema``, message
encoding ``json``)::

    {"timestamps_ns": [int, ...], "accel": [[ax, ay, az], ...]}

one or many samples per message (devices batch samples into radio packets);
the channel's metadata ``unit`` is ``m/s^2`` (default) or ``g``.

Decoding, fast path: all payloads of a channel as newline-delimited JSON
through Arrow's C++ reader (``pyarrow``, which rerun-sdk depends on), one
thread, explicit schema — ~3× faster than :func:`json.loads`, same values
(correctly rounded).  Exact path, for anything Arrow does not take (``NaN``,
a missing key, pretty-printed messages, no pyarrow): the payloads joined into
one JSON array, one :func:`json.loads`, flattened with
:func:`itertools.chain` and :func:`numpy.fromiter`; it also words the errors.
Its floor is CPython's decimal-to-binary conversion (~0.35 µs per 17-digit
float) plus ~2 µs of object building per message.  (A vectorised numpy
parser was tried and measured slower than ``float()``: digit-by-digit array
passes cost as much per byte.)
"""

from __future__ import annotations

import json
from itertools import chain

import numpy as np

from wheelcal.io.mcap_scan import MessageBlock

ACCEL_BATCH_SCHEMA_NAME = "wheelcal.AccelBatch"
JSON_SCHEMA_ENCODING = "jsonschema"
JSON_MESSAGE_ENCODING = "json"
UNIT_KEY = "unit"
UNITS = ("m/s^2", "g")

ACCEL_BATCH_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": ACCEL_BATCH_SCHEMA_NAME,
    "description": "Accelerometer samples; unit from the channel metadata 'unit' "
    "('m/s^2' default, or 'g' = 9.80665 m/s^2).",
    "type": "object",
    "properties": {
        "timestamps_ns": {
            "type": "array",
            "items": {"type": "integer"},
            "description": "Sample times, nanoseconds since the Unix epoch.",
        },
        "accel": {
            "type": "array",
            "items": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
            "description": "One [ax, ay, az] per timestamp.",
        },
    },
    "required": ["timestamps_ns", "accel"],
}


class AccelBatchError(ValueError):
    """JSON messages that do not follow the ``wheelcal.AccelBatch`` layout."""


def schema_bytes() -> bytes:
    """The JSON Schema of ``wheelcal.AccelBatch``, as stored in the MCAP Schema record."""
    return json.dumps(ACCEL_BATCH_SCHEMA, indent=2).encode("utf-8")


def decode_accel_blocks(blocks: tuple[MessageBlock, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Timestamps and samples of all ``wheelcal.AccelBatch`` messages of a channel.

    Parameters
    ----------
    blocks:
        Message blocks of one channel, from :func:`~wheelcal.io.mcap_scan.scan_mcap`.

    Returns
    -------
    time_ns : ndarray of int64, shape (N,)
    accel : ndarray, shape (N, 3)
        In the channel's unit (the caller converts ``g``).

    Raises
    ------
    AccelBatchError
        Invalid JSON, missing keys, non-integer stamps, or rows that are not
        three numbers or do not match the stamps one to one.
    """
    payloads = [
        block.buffer[start : start + length]
        for block in blocks
        for start, length in zip(
            block.payload_offsets.tolist(), block.payload_lengths.tolist(), strict=True
        )
    ]
    if not payloads:
        return np.empty(0, np.int64), np.empty((0, 3))
    fast = _decode_with_arrow(payloads)
    if fast is not None:
        return fast
    joined = b"[" + b",".join(payloads) + b"]"
    try:
        messages = json.loads(joined)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        bad = _message_at(payloads, getattr(exc, "pos", 0))
        raise AccelBatchError(f"message {bad} is not valid JSON ({exc})") from None
    if len(messages) != len(payloads):
        raise AccelBatchError("a message holds more than one JSON value")
    try:
        stamps = [m["timestamps_ns"] for m in messages]
        rows = [m["accel"] for m in messages]
    except (KeyError, TypeError):
        raise AccelBatchError(
            'every message needs "timestamps_ns" and "accel" (wheelcal.AccelBatch)'
        ) from None
    if any(len(s) != len(r) for s, r in zip(stamps, rows, strict=True)):
        raise AccelBatchError('a message has different numbers of "timestamps_ns" and "accel"')
    time_ns = np.array(list(chain.from_iterable(stamps)))
    if time_ns.size and time_ns.dtype.kind != "i":  # floats, strings, or beyond int64
        raise AccelBatchError('"timestamps_ns" must be integers (int64 nanoseconds)')
    flat_rows = list(chain.from_iterable(rows))
    try:
        widths = np.fromiter(map(len, flat_rows), np.int64, len(flat_rows))
        if widths.size and (widths.min() != 3 or widths.max() != 3):
            raise ValueError
        accel = np.fromiter(chain.from_iterable(flat_rows), np.float64, 3 * len(flat_rows))
    except (ValueError, TypeError):
        raise AccelBatchError('every "accel" row must be three numbers [ax, ay, az]') from None
    return time_ns.astype(np.int64), accel.reshape(-1, 3)


def _decode_with_arrow(payloads: list) -> tuple[np.ndarray, np.ndarray] | None:
    """Parse with Arrow's C++ JSON reader (single thread), or None to use json.loads.

    Arrow parses numbers with correctly rounded conversions (same values as
    :func:`json.loads`) at several times the speed.  Anything it cannot take
    — a payload with a newline (not line-delimited), ``NaN``, missing keys,
    non-integer stamps — returns None and the exact, judging path runs.
    """
    try:
        import pyarrow as pa
        import pyarrow.json as pa_json
    except ImportError:  # rerun-sdk brings pyarrow; without it, json.loads still works
        return None
    joined = b"\n".join(payloads)
    if joined.count(b"\n") != len(payloads) - 1:
        return None
    schema = pa.schema(
        [("timestamps_ns", pa.list_(pa.int64())), ("accel", pa.list_(pa.list_(pa.float64())))]
    )
    try:
        table = pa_json.read_json(
            pa.BufferReader(joined),
            read_options=pa_json.ReadOptions(use_threads=False, block_size=len(joined) + 1),
            parse_options=pa_json.ParseOptions(
                explicit_schema=schema, unexpected_field_behavior="ignore"
            ),
        )
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return None
    if table.num_rows != len(payloads):
        return None
    stamps = table.column("timestamps_ns").combine_chunks()
    batches = table.column("accel").combine_chunks()
    rows = batches.flatten()
    if stamps.null_count or batches.null_count or rows.null_count:
        return None
    values = rows.flatten()
    if values.null_count or stamps.flatten().null_count:
        return None
    per_message_stamps = stamps.value_lengths().to_numpy(zero_copy_only=False)
    per_message_rows = batches.value_lengths().to_numpy(zero_copy_only=False)
    if not np.array_equal(per_message_stamps, per_message_rows):
        raise AccelBatchError('a message has different numbers of "timestamps_ns" and "accel"')
    widths = rows.value_lengths().to_numpy(zero_copy_only=False)
    if widths.size and (widths.min() != 3 or widths.max() != 3):
        raise AccelBatchError('every "accel" row must be three numbers [ax, ay, az]')
    time_ns = stamps.flatten().to_numpy(zero_copy_only=False).astype(np.int64)
    accel = values.to_numpy(zero_copy_only=False).astype(np.float64).reshape(-1, 3)
    return time_ns, accel


def _message_at(payloads: list[bytes], pos: int) -> int:
    """Index of the message that holds byte ``pos`` of the joined array."""
    ends = np.cumsum([len(p) + 1 for p in payloads])
    return int(np.searchsorted(ends, pos, side="right"))


def encode_accel_batches(
    time_ns: np.ndarray, accel: np.ndarray, batch_size: int
) -> list[tuple[int, bytes]]:
    """``wheelcal.AccelBatch`` payloads of up to ``batch_size`` samples each.

    Floats are written with Python's shortest round-trip repr, so reading the
    file back gives the same float64 values bit for bit.

    Returns
    -------
    list of (log_time_ns, payload)
        The log time of a batch is the stamp of its last sample (when a device
        would send it).
    """
    if batch_size < 1:
        raise ValueError(f"batch_size must be at least 1, got {batch_size}")
    stamps = np.asarray(time_ns, dtype=np.int64).tolist()
    rows = np.asarray(accel, dtype=float).reshape(-1, 3).tolist()
    out = []
    for i in range(0, len(stamps), batch_size):
        batch_stamps = stamps[i : i + batch_size]
        payload = json.dumps(
            {"timestamps_ns": batch_stamps, "accel": rows[i : i + batch_size]},
            separators=(",", ":"),
        )
        out.append((batch_stamps[-1], payload.encode("utf-8")))
    return out
