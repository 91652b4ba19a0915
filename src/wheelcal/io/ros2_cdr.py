"""What every stamped ROS 2 message in CDR shares: its header, its layout, its definitions.

A ROS 2 message in CDR is a 4-byte encapsulation header (``00 01 00 00`` for
little-endian CDR, ``00 00 ..`` for big-endian) followed by the fields, each
aligned to its own size *relative to the end of that header*.  A stamped
message starts with a ``std_msgs/Header``; with ``L`` its ``frame_id``
string's length field (bytes including the NUL) and ``q = align8(12 + L)``::

    offset  field
    0       header.stamp.sec            int32
    4       header.stamp.nanosec        uint32
    8       header.frame_id length L    uint32
    12      frame_id bytes + NUL        L bytes, then padding to a multiple of 8
    q       the message's own fields    (``tail_bytes`` of fixed-size fields)

so a message of a type whose own fields are all of fixed size is
``4 + q + tail_bytes`` bytes (CDR allows up to 3 bytes of final padding).
Decoding needs one integer per message (``L``) and gathers — no per-message
Python (:func:`stamped_messages`); encoding is one structured array
(:func:`stamped_records`).  The message definitions of the header's types,
which ``ros2 bag record`` appends to every stamped type's, are here once
(:func:`message_definition`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.io.mcap_scan import MessageBlock

ROS2_SCHEMA_ENCODING = "ros2msg"
CDR_MESSAGE_ENCODING = "cdr"
CDR_LE = b"\x00\x01\x00\x00"
_NS_PER_S = 1_000_000_000

#: The definitions of the types stamped messages use, as ``ros2 bag record`` stores them.
_DEFINITIONS = {
    "geometry_msgs/Quaternion": """\
# This represents an orientation in free space in quaternion form.

float64 x 0
float64 y 0
float64 z 0
float64 w 1
""",
    "geometry_msgs/Vector3": """\
# This represents a vector in free space.

float64 x
float64 y
float64 z
""",
    "std_msgs/Header": """\
# Standard metadata for higher-level stamped data types.

builtin_interfaces/Time stamp

string frame_id
""",
    "builtin_interfaces/Time": """\
# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

int32 sec
uint32 nanosec
""",
}


def message_definition(own: str, *dependencies: str) -> str:
    """A type's definition as ``ros2 bag record`` stores it: its own text, then each dependency's.

    Each dependency (a key of the definitions above) follows a line of 80 ``=``
    and ``MSG: <type>``.
    """
    parts = [own]
    for name in dependencies:
        parts.append(f"\n{'=' * 80}\nMSG: {name}\n{_DEFINITIONS[name]}")
    return "".join(parts)


def gather(arr: np.ndarray, at: np.ndarray, dtype: str, count: int = 1) -> np.ndarray:
    """Values of ``dtype`` (count per message) starting at byte positions ``at``.

    Messages of one fixed-size type sit at a constant stride in a chunk; then a
    strided view reads them without building a byte index (the general case).
    """
    item = np.dtype(dtype).itemsize
    size = item * count
    if at.size > 1:
        step = int(at[1] - at[0])
        if step >= size and np.all(np.diff(at) == step):
            view = np.ndarray(
                (at.size, count), dtype=dtype, buffer=arr, offset=int(at[0]), strides=(step, item)
            )
            return view.reshape(-1) if count == 1 else view.copy()
    raw = arr[at[:, None] + np.arange(size)]
    out = raw.view(dtype)
    return out.reshape(-1) if count == 1 else out.reshape(-1, count)


@dataclass(frozen=True)
class StampedHeader:
    """The ``std_msgs/Header`` of one block's messages of one byte order."""

    sec: np.ndarray
    nsec: np.ndarray
    body: np.ndarray  # byte offset of each message's body (after the 4-byte encapsulation)
    q: np.ndarray  # the header's size, padded to 8 (the first field after it starts there)
    #: (block index, its size, the size its layout needs) of the first message of the
    #: wrong size, or None.
    wrong_size: tuple[int, int, int] | None


def stamped_header(
    arr: np.ndarray, block: MessageBlock, sel: np.ndarray, endian: str, tail_bytes: int
) -> StampedHeader:
    """Stamps and layout of the messages ``sel`` of ``block`` (one byte order).

    A stamped message is the header (stamp, frame_id string) and ``tail_bytes``
    of fixed fields after it, 8-aligned; CDR allows up to 3 bytes of final
    padding (XCDR options field).
    """
    body = block.payload_offsets[sel] + 4
    sec = gather(arr, body, endian + "i4")
    nsec = gather(arr, body + 4, endian + "u4")
    str_len = gather(arr, body + 8, endian + "u4").astype(np.int64)
    q = (12 + str_len + 7) // 8 * 8
    expected = 4 + q + tail_bytes
    actual = block.payload_lengths[sel]
    wrong = (actual < expected) | (actual > expected + 3)
    wrong_size = None
    if np.any(wrong):
        at = int(np.argmax(wrong))
        wrong_size = (int(sel[at]), int(actual[at]), int(expected[at]))
    return StampedHeader(sec, nsec, body, q, wrong_size)


@dataclass(frozen=True, eq=False)
class StampedMessages:
    """One block's messages of a stamped type, checked: their stamps and fields' positions."""

    arr: np.ndarray  # the block's bytes
    stamp_ns: np.ndarray  # header.stamp, int64 ns
    #: Per byte order present: (``"<"`` or ``">"``, the messages, where their own fields start).
    parts: tuple[tuple[str, np.ndarray, np.ndarray], ...]


def stamped_messages(
    block: MessageBlock, type_name: str, tail_bytes: int, first_message: int, error: type
) -> StampedMessages:
    """The stamps and layout of ``block``'s messages of ``type_name``, every one checked.

    ``first_message`` is the channel's index of the block's first message, for
    messages; ``error`` (a ``ValueError``) is raised for a message that is too
    short, not plain CDR, of the wrong size for the layout, or stamped with
    ``nanosec`` ≥ 10⁹.
    """
    arr = np.frombuffer(block.buffer, dtype=np.uint8)
    off = block.payload_offsets
    short = block.payload_lengths < 4 + 16 + tail_bytes  # frame_id holds its NUL at least
    if np.any(short):
        at = int(np.argmax(short))
        raise error(
            f"message {first_message + at} is too short to be a {type_name} "
            f"({int(block.payload_lengths[at])} bytes)"
        )
    kind = arr[off + 1]
    bad = (arr[off] != 0) | (kind > 1)
    if np.any(bad):
        raise error(
            f"message {first_message + int(np.argmax(bad))} is not plain CDR "
            "(encapsulation kind is not CDR_LE/BE)"
        )
    sec = np.empty(off.size, np.int64)
    nsec = np.empty(off.size, np.int64)
    parts = []
    for endian, code in (("<", 1), (">", 0)):
        sel = np.flatnonzero(kind == code)
        if sel.size == 0:
            continue
        header = stamped_header(arr, block, sel, endian, tail_bytes)
        sec[sel], nsec[sel] = header.sec, header.nsec
        if header.wrong_size is not None:
            at, actual, expected = header.wrong_size
            raise error(
                f"message {first_message + at}'s size does not match the "
                f"{type_name} layout ({actual} bytes, expected {expected})"
            )
        parts.append((endian, sel, header.body + header.q))
    late = nsec >= _NS_PER_S
    if np.any(late):
        raise error(
            f"message {first_message + int(np.argmax(late))}: header.stamp.nanosec is 1e9 or more"
        )
    return StampedMessages(arr, sec * _NS_PER_S + nsec, tuple(parts))


def stamped_records(
    time_ns: np.ndarray, frame_id: str, fields: list[tuple[str, object, int]], tail_bytes: int
) -> np.ndarray:
    """Little-endian CDR records of a stamped type, header filled in, its own fields zero.

    ``fields`` are (name, numpy format, offset from the end of the header) of
    the type's own fields; fill them, then :func:`payloads`.
    """
    name = frame_id.encode("utf-8") + b"\x00"
    q = (12 + len(name) + 7) // 8 * 8
    dtype = np.dtype(
        {
            "names": ["encap", "sec", "nsec", "str_len", "frame", *(f[0] for f in fields)],
            "formats": ["V4", "<i4", "<u4", "<u4", f"V{len(name)}", *(f[1] for f in fields)],
            "offsets": [0, 4, 8, 12, 16, *(4 + q + f[2] for f in fields)],
            "itemsize": 4 + q + tail_bytes,
        }
    )
    rec = np.zeros(time_ns.size, dtype=dtype)
    rec["encap"] = np.void(CDR_LE)
    sec, nsec = np.divmod(time_ns, _NS_PER_S)
    if np.any(sec > np.iinfo(np.int32).max) or np.any(sec < np.iinfo(np.int32).min):
        raise ValueError("stamps outside the int32 seconds range of builtin_interfaces/Time")
    rec["sec"] = sec
    rec["nsec"] = nsec
    rec["str_len"] = len(name)
    rec["frame"] = np.void(name)
    return rec


def payloads(records: np.ndarray) -> list[bytes]:
    """One message payload per record."""
    raw = records.tobytes()
    size = records.dtype.itemsize
    return [raw[i : i + size] for i in range(0, len(raw), size)]
