"""``wheelcal.AccelBatch`` JSON messages: schema, encoding and fast decoding.

The contract's second input format (schema encoding ``jsonschema``, message
encoding ``json``)::

    {"timestamps_ns": [int, ...], "accel": [[ax, ay, az], ...]}

one or many samples per message (devices batch samples into radio packets);
the channel's metadata ``unit`` is ``m/s^2`` (default) or ``g``.  Optional,
additive (issue 13): ``"gyro": [[gx, gy, gz], ...]``, one row per timestamp
(a row may be ``null``: no reading for that sample), in the unit of the
channel metadata ``gyro_unit`` — ``rad/s`` (default) or ``deg/s`` — and
``"temperature_c": [...]``, one value (°C, or ``null``) per timestamp.  A
message may carry either or both, or neither: samples of messages without
them have no reading (NaN).

Decoding, fastest path: a block of messages that are all exactly
``{"timestamps_ns":[INT],"accel":[[NUM,NUM,NUM]]}`` (one sample each, compact)
is cut into numbers with vectorised checks and parsed by Arrow's casts
(:mod:`wheelcal.io.accel_json_single`; anything else falls through).
Fast path: all payloads of a channel as newline-delimited JSON
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
from dataclasses import dataclass
from itertools import chain

import numpy as np

from wheelcal.io.accel_json_single import blank_runs, decode_single_samples
from wheelcal.io.channel_format import ChannelFormat
from wheelcal.io.growing import ColumnSink
from wheelcal.io.mcap_scan import RECORD_GAP_BYTES, MessageBlock

ACCEL_BATCH_SCHEMA_NAME = "wheelcal.AccelBatch"
JSON_SCHEMA_ENCODING = "jsonschema"
JSON_MESSAGE_ENCODING = "json"
UNIT_KEY = "unit"  # the channel metadata: "m/s^2" or "g" (recording.ACCEL_UNITS)
GYRO_UNIT_KEY = "gyro_unit"

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
        "gyro": {
            "type": "array",
            "items": {
                "type": ["array", "null"],
                "items": {"type": "number"},
                "minItems": 3,
                "maxItems": 3,
            },
            "description": "Optional: one [gx, gy, gz] (or null) per timestamp; unit from the "
            "channel metadata 'gyro_unit' ('rad/s' default, or 'deg/s').",
        },
        "temperature_c": {
            "type": "array",
            "items": {"type": ["number", "null"]},
            "description": "Optional: sensor temperature in degrees Celsius per timestamp.",
        },
    },
    "required": ["timestamps_ns", "accel"],
}


class AccelBatchError(ValueError):
    """JSON messages that do not follow the ``wheelcal.AccelBatch`` layout."""


def schema_bytes() -> bytes:
    """The JSON Schema of ``wheelcal.AccelBatch``, as stored in the MCAP Schema record."""
    return json.dumps(ACCEL_BATCH_SCHEMA, indent=2).encode("utf-8")


ACCEL_BATCH_FORMAT = ChannelFormat(
    ACCEL_BATCH_SCHEMA_NAME, JSON_SCHEMA_ENCODING, JSON_MESSAGE_ENCODING, schema_bytes()
)


@dataclass(frozen=True, eq=False)
class AccelBatchArrays:
    """All samples of a ``wheelcal.AccelBatch`` channel, in the channel's units.

    ``gyro`` (N, 3) and ``temperature_c`` (N,) are ``None`` when no message
    carries them, else NaN where a message or a row gives no value.
    """

    time_ns: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray | None = None
    temperature_c: np.ndarray | None = None


def decode_accel_batch(
    blocks: tuple[MessageBlock, ...], optional: bool = True, first_message: int = 0
) -> AccelBatchArrays:
    """Stamps and samples (in the channel's unit) of one channel's ``wheelcal.AccelBatch`` blocks.

    ``optional=False`` ignores ``gyro`` and ``temperature_c`` (they are then not
    even parsed); ``first_message`` is the channel's index of the first message
    (for errors).

    Raises
    ------
    AccelBatchError
        Invalid JSON, missing keys, non-integer stamps, rows that are not three
        numbers or do not match the stamps one to one; a ``gyro`` row that is
        neither three numbers nor null, or a ``gyro``/``temperature_c`` list
        whose length differs from the message's ``timestamps_ns``.
    """
    if len(blocks) == 1:
        single = decode_single_samples(blocks[0])
        if single is not None:
            return AccelBatchArrays(*single)
    payloads = None
    joined_lines = _lines_in_place(blocks)
    if joined_lines is None:
        payloads = _payload_list(blocks)
        if not payloads:
            return AccelBatchArrays(np.empty(0, np.int64), np.empty((0, 3)))
        joined_lines = b"\n".join(payloads)
    count = sum(block.count for block in blocks)
    # Accelerometer-only files stay on the old path.  A one-byte search (memchr, ~40× faster
    # than a substring search) for a letter that neither the required keys nor JSON numbers
    # contain ("g" of "gyro", "u" of "temperature_c") rules the keys out first.
    want_gyro = optional and b"g" in joined_lines and b'"gyro"' in joined_lines
    want_temp = optional and b"u" in joined_lines and b'"temperature_c"' in joined_lines
    fast = _decode_with_arrow(count, joined_lines, want_gyro, want_temp)
    if fast is not None:
        return fast
    if payloads is None:
        payloads = _payload_list(blocks)
    joined = b"[" + b",".join(payloads) + b"]"
    try:
        messages = json.loads(joined)
    except json.JSONDecodeError as exc:
        bad = first_message + _message_at(payloads, exc.pos)
        raise AccelBatchError(f"message {bad} is not valid JSON ({exc})") from None
    except UnicodeDecodeError as exc:
        bad = first_message + _message_at(payloads, exc.start)
        raise AccelBatchError(f"message {bad} is not valid UTF-8 ({exc.reason})") from None
    except RecursionError:
        bad = first_message + _first_too_deep(payloads)
        raise AccelBatchError(
            f"message {bad} is nested too deeply to be a wheelcal.AccelBatch (corrupt)"
        ) from None
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
    counts = [len(s) for s in stamps]
    gyro = _optional_rows(messages, counts, "gyro", 3) if want_gyro else None
    temp = _optional_rows(messages, counts, "temperature_c", 0) if want_temp else None
    return AccelBatchArrays(time_ns.astype(np.int64), accel.reshape(-1, 3), gyro, temp)


def _number(value) -> float:
    if value is None:
        return np.nan
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError
    return float(value)


def _optional_rows(messages: list, counts: list[int], key: str, width: int) -> np.ndarray | None:
    """Values of an optional per-sample key (NaN where absent or null); None if no message has it.

    ``width`` 3 reads ``[x, y, z]`` rows (or null), 0 reads scalars (or null).
    """
    shape = (sum(counts), width) if width else (sum(counts),)
    out = np.full(shape, np.nan)
    found = False
    at = 0
    what = "three numbers or null" if width else "a number or null"
    for message, count in zip(messages, counts, strict=True):
        values = message.get(key) if isinstance(message, dict) else None
        if values is not None:
            found = True
            if not isinstance(values, list) or len(values) != count:
                raise AccelBatchError(
                    f'a message has different numbers of "timestamps_ns" and "{key}"'
                )
            try:
                for i, value in enumerate(values):
                    if value is None:
                        continue
                    if width:
                        if not isinstance(value, list) or len(value) != width:
                            raise TypeError
                        out[at + i] = [_number(v) for v in value]
                    else:
                        out[at + i] = _number(value)
            except TypeError:
                raise AccelBatchError(f'every "{key}" entry must be {what}') from None
        at += count
    return out if found else None


def _payload_list(blocks: tuple[MessageBlock, ...]) -> list:
    """Every message payload of the blocks, in order (one bytes object each)."""
    return [
        block.buffer[start : start + length]
        for block in blocks
        for start, length in zip(
            block.payload_offsets.tolist(), block.payload_lengths.tolist(), strict=True
        )
    ]


def _lines_in_place(blocks: tuple[MessageBlock, ...]) -> bytearray | None:
    """The payloads of one block as lines, without a Python object per message, or None.

    When a chunk holds only this channel's messages back to back, the payloads
    are separated by exactly the 31 header bytes of each next record: a copy of
    the stretch with those bytes made a newline and 30 blanks (JSON white space
    before the next line's value) is the newline-delimited text.  Otherwise None.
    """
    if len(blocks) != 1 or blocks[0].count < 2 or not blocks[0].back_to_back():
        return None
    block = blocks[0]
    first, last = block.span()
    lines = bytearray(memoryview(block.buffer)[first:last])  # one copy, written in place
    gap_starts = block.payload_offsets[:-1] + block.payload_lengths[:-1]
    blank_runs(np.frombuffer(lines, np.uint8), gap_starts - first, RECORD_GAP_BYTES, ord("\n"))
    return lines


def _decode_with_arrow(
    count: int, joined: bytes, want_gyro: bool, want_temp: bool
) -> AccelBatchArrays | None:
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
    if joined.count(b"\n") != count - 1:
        return None
    fields = [("timestamps_ns", pa.list_(pa.int64())), ("accel", pa.list_(pa.list_(pa.float64())))]
    if want_gyro:
        fields.append(("gyro", pa.list_(pa.list_(pa.float64()))))
    if want_temp:
        fields.append(("temperature_c", pa.list_(pa.float64())))
    try:
        table = pa_json.read_json(
            pa.BufferReader(joined),
            read_options=pa_json.ReadOptions(use_threads=False, block_size=len(joined) + 1),
            parse_options=pa_json.ParseOptions(
                explicit_schema=pa.schema(fields), unexpected_field_behavior="ignore"
            ),
        )
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return None
    if table.num_rows != count:
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
    gyro = temp = None
    if want_gyro:
        gyro = _arrow_optional(table.column("gyro").combine_chunks(), per_message_stamps, 3)
    if want_temp:
        temp = _arrow_optional(
            table.column("temperature_c").combine_chunks(), per_message_stamps, 0
        )
    return AccelBatchArrays(time_ns, accel, gyro, temp)


def _arrow_optional(column, per_message: np.ndarray, width: int) -> np.ndarray | None:
    """NaN-filled (N, width) or (N,) values of an optional list column (null = absent)."""
    present = ~column.is_null().to_numpy(zero_copy_only=False)
    if not np.any(present):
        return None
    key = '"gyro"' if width else '"temperature_c"'
    lengths = np.nan_to_num(column.value_lengths().to_numpy(zero_copy_only=False)).astype(np.int64)
    if np.any(lengths[present] != per_message[present]):
        raise AccelBatchError(f'a message has different numbers of "timestamps_ns" and {key}')
    n = int(per_message.sum())
    where = np.repeat(present, per_message)  # samples whose message carries the key
    items = column.flatten()  # only the present messages' entries, in order
    if not width:
        out = np.full(n, np.nan)
        out[where] = items.to_numpy(zero_copy_only=False).astype(np.float64)
        return out
    out = np.full((n, width), np.nan)
    row_ok = ~items.is_null().to_numpy(zero_copy_only=False)
    widths = np.nan_to_num(items.value_lengths().to_numpy(zero_copy_only=False)).astype(np.int64)
    if np.any(widths[row_ok] != width):
        raise AccelBatchError(f"every {key} entry must be three numbers or null")
    values = items.flatten().to_numpy(zero_copy_only=False).astype(np.float64)
    block = np.full((row_ok.size, width), np.nan)
    block[row_ok] = values.reshape(-1, width)
    out[where] = block
    return out


def _first_too_deep(payloads: list[bytes]) -> int:
    """Index of the first payload that :func:`json.loads` cannot parse for its depth."""
    for i, payload in enumerate(payloads):
        try:
            json.loads(bytes(payload))  # payloads may be memoryviews of the mapped file
        except RecursionError:
            return i
        except ValueError:
            continue
    return 0


class AccelBatchSink(ColumnSink):
    """Decodes an AccelBatch channel block by block as the scan finds it (see ``scan_mcap``).

    Keeps the decoded columns only (no message text); a decoding error is kept
    and raised by :meth:`result`.
    """

    errors = (AccelBatchError,)

    def __init__(self) -> None:
        super().__init__()
        self._optional_error: AccelBatchError | None = None

    def decode(self, block: MessageBlock, first_message: int) -> dict[str, np.ndarray | None]:
        """One block's samples, and its gyro and temperature if it has them."""
        try:
            out = decode_accel_batch((block,), optional=True, first_message=first_message)
        except AccelBatchError as exc:
            try:  # a defect in the optional gyro / temperature only matters if they are read
                out = decode_accel_batch((block,), optional=False, first_message=first_message)
            except AccelBatchError:
                raise exc from None
            self._optional_error = self._optional_error or exc
        return {
            "time_ns": out.time_ns,
            "accel": out.accel,
            "gyro": out.gyro,
            "temperature_c": out.temperature_c,
        }

    def result(self, optional: bool = True) -> AccelBatchArrays:
        """All samples of the channel; raises the first decoding error.

        ``optional=False``: errors in ``gyro`` / ``temperature_c`` do not count.
        """
        columns = self.columns()
        if optional and self._optional_error is not None:
            raise self._optional_error
        if not columns:
            return AccelBatchArrays(np.empty(0, np.int64), np.empty((0, 3)))
        return AccelBatchArrays(
            columns["time_ns"], columns["accel"], columns.get("gyro"), columns.get("temperature_c")
        )


def _message_at(payloads: list[bytes], pos: int) -> int:
    """Index of the message that holds byte ``pos`` of the joined array."""
    ends = np.cumsum([len(p) + 1 for p in payloads])
    return int(np.searchsorted(ends, pos, side="right"))


def encode_accel_batches(
    time_ns: np.ndarray,
    accel: np.ndarray,
    batch_size: int,
    gyro: np.ndarray | None = None,
    temperature_c: np.ndarray | None = None,
) -> list[tuple[int, bytes]]:
    """``wheelcal.AccelBatch`` payloads of up to ``batch_size`` samples each.

    Floats are written with Python's shortest round-trip repr, so reading the
    file back gives the same float64 values bit for bit.  ``gyro`` (N, 3) and
    ``temperature_c`` (N,) are written when given; a gyro row with a NaN is
    written as ``null`` (no reading), as is a NaN temperature.

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
    extra: dict[str, list] = {}
    if gyro is not None:
        rate = np.asarray(gyro, dtype=float).reshape(-1, 3)
        if rate.shape[0] != len(stamps):
            raise ValueError(f"{len(stamps)} stamps but {rate.shape[0]} gyro rows")
        ok = np.all(np.isfinite(rate), axis=1).tolist()
        extra["gyro"] = [r if good else None for r, good in zip(rate.tolist(), ok, strict=True)]
    if temperature_c is not None:
        temp = np.asarray(temperature_c, dtype=float).reshape(-1)
        if temp.size != len(stamps):
            raise ValueError(f"{len(stamps)} stamps but {temp.size} temperatures")
        extra["temperature_c"] = [v if np.isfinite(v) else None for v in temp.tolist()]
    out = []
    for i in range(0, len(stamps), batch_size):
        batch_stamps = stamps[i : i + batch_size]
        message = {"timestamps_ns": batch_stamps, "accel": rows[i : i + batch_size]}
        for key, values in extra.items():
            message[key] = values[i : i + batch_size]
        payload = json.dumps(message, separators=(",", ":"))
        out.append((batch_stamps[-1], payload.encode("utf-8")))
    return out
