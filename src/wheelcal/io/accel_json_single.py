r"""Fast decoding of the commonest ``wheelcal.AccelBatch`` shape: one sample per message.

A device that sends every sample on its own writes messages that are all::

    {"timestamps_ns":[INT],"accel":[[NUM,NUM,NUM]]}

byte for byte (compact separators, the keys in this order, nothing else).
Arrow's JSON reader spends ~0.8 µs per such tiny record building nested
lists; Arrow's string-to-number casts parse the same numbers (exact for
integers, correctly rounded for floats: the values of :func:`json.loads`)
several times faster.  So, for a block whose messages lie back to back in
one buffer (one channel's records in a chunk):

1. the ``]`` after each stamp is found (the only layout-dependent position),
   the fixed text around the numbers is checked byte for byte against the
   layout above, and stamps and numbers are cut out in vectorised passes;
2. every number byte is checked to follow JSON's number grammar
   (``-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?``) with neighbour tests
   — Arrow also takes ``.5``, ``5.``, ``+5``, ``01``, ``inf``, ``nan`` and
   blanks, which JSON does not, so those are refused here; what neighbour
   tests cannot see (two dots or exponents in one number) Arrow refuses;
3. Arrow casts the stamps to int64 and the numbers to float64.

Any deviation — another layout, a key order, white space, a ``gyro`` or
``temperature_c``, a number that is not plain JSON, a message Arrow refuses —
returns ``None``, and :func:`wheelcal.io.accel_json.decode_accel_batch` takes
its general path, which accepts what it should and names what is corrupt
exactly as before.  This path never raises for bad input.
"""

from __future__ import annotations

import numpy as np

from wheelcal.io.mcap_scan import MESSAGE_HEADER_BYTES, MessageBlock

_PREFIX = b'{"timestamps_ns":['
_MIDDLE = b'],"accel":[['
_SUFFIX = b"]]}"
_RECORD_GAP = 9 + MESSAGE_HEADER_BYTES  # a Message record's opcode and length, then its header
# the shortest such message: one digit for the stamp, "0,0,0" for the sample
_SHORTEST = len(_PREFIX) + 1 + len(_MIDDLE) + 5 + len(_SUFFIX)
_COMMA, _CLOSE, _ZERO_BYTE = ord(","), ord("]"), ord("0")
_GAP, _FIXED, _STAMP, _NUMBER = range(4)  # what each byte of the stretch is


def decode_single_samples(block: MessageBlock) -> tuple[np.ndarray, np.ndarray] | None:
    """Stamps (int64, (N,)) and samples ((N, 3)) of a block of one-sample messages, or None.

    ``None`` unless every message of ``block`` has exactly the layout of the
    module docstring and its messages lie back to back in the buffer (one
    channel's records, nothing between them); the caller then decodes the
    block with the general path.
    """
    n = block.count
    if n == 0:
        return None
    starts, lengths = block.payload_offsets, block.payload_lengths
    if lengths.min() < _SHORTEST:
        return None
    if n > 1 and not np.all(starts[1:] - (starts[:-1] + lengths[:-1]) == _RECORD_GAP):
        return None
    first = int(starts[0])
    stretch = np.frombuffer(
        block.buffer, np.uint8, count=int(starts[-1] + lengths[-1]) - first, offset=first
    )
    begin = starts - first
    end = begin + lengths
    # one look at the first message turns away other shapes (several samples) at no cost
    sample = stretch[: end[0]].tobytes()
    if sample.count(b",") != 3 or not sample.startswith(_PREFIX) or not sample.endswith(_SUFFIX):
        return None
    middle = _stamp_ends(stretch, begin, end)
    if middle is None:
        return None
    stamp_digits = middle - begin - len(_PREFIX)
    number_bytes = end - len(_SUFFIX) - middle - len(_MIDDLE)
    if stamp_digits.min() < 1 or number_bytes.min() < 5:
        return None
    # per message: prefix | stamp | middle | numbers and the suffix's "]" | rest of the suffix
    # | record gap (none after the last); the "]" becomes the "," before the next message's
    counts = np.empty((n, 6), np.int64)
    counts[:] = (len(_PREFIX), 0, len(_MIDDLE), 0, len(_SUFFIX) - 1, _RECORD_GAP)
    counts[:, 1] = stamp_digits
    counts[:, 3] = number_bytes + 1
    counts[-1, 3:] = (number_bytes[-1], len(_SUFFIX), 0)
    labels = np.repeat(
        np.tile(np.array([_FIXED, _STAMP, _FIXED, _NUMBER, _FIXED, _GAP], np.uint8), n),
        counts.reshape(-1),
    )
    fixed = stretch[labels == _FIXED].tobytes()
    if fixed != (_PREFIX + _MIDDLE + _SUFFIX[1:]) * (n - 1) + _PREFIX + _MIDDLE + _SUFFIX:
        return None
    time_ns = _stamps(stretch[labels == _STAMP], stamp_digits)
    if time_ns is None:
        return None
    numbers = stretch[labels == _NUMBER]
    ours = np.cumsum(number_bytes + 1)[:-1] - 1  # where each message's "]" landed
    if not np.all(numbers[ours] == _CLOSE):  # the suffix's first byte, not checked as fixed
        return None
    numbers[ours] = _COMMA
    accel = _samples(numbers, ours, n)
    if accel is None:
        return None
    return time_ns, accel


def _stamp_ends(stretch: np.ndarray, begin: np.ndarray, end: np.ndarray) -> np.ndarray | None:
    """Where each message's ``]`` after its stamp is, or None if not found.

    Stamps mostly have the same number of digits: if the first message's
    width puts a ``]`` at the same place in every message, that is taken (the
    checks that follow refuse a stamp that is not all digits, so it is then
    the first ``]``).  Otherwise: the first of exactly three ``]`` per message.
    """
    width = stretch[begin[0] + len(_PREFIX) : end[0]].tobytes().find(b"]")
    if width > 0:
        guess = begin + len(_PREFIX) + width
        if np.all(guess < end) and np.all(stretch[guess] == _CLOSE):
            return guess
    closes = np.flatnonzero(stretch == _CLOSE)
    owner = np.searchsorted(begin, closes, side="right") - 1
    closes = closes[closes < end[owner]]  # not in the record headers between the payloads
    if closes.size != 3 * begin.size:
        return None
    by_message = closes.reshape(-1, 3)
    if not (
        np.array_equal(by_message[:, 1], end - 2 - 1) and np.array_equal(by_message[:, 2], end - 2)
    ):
        return None
    return by_message[:, 0]


# Byte classes for the number check, and which class may follow which.
_OTHER, _SEP, _ZERO, _DIGIT, _DOT, _EXP, _PLUS, _MINUS = range(8)
_CLASS = np.full(256, _OTHER, np.uint8)
_CLASS[_COMMA] = _SEP
_CLASS[ord("0")] = _ZERO
_CLASS[ord("1") : ord("9") + 1] = _DIGIT
_CLASS[ord(".")] = _DOT
_CLASS[[ord("e"), ord("E")]] = _EXP
_CLASS[ord("+")] = _PLUS
_CLASS[ord("-")] = _MINUS
_FOLLOWS = {  # JSON's number grammar, byte to next byte; numbers are separated by _SEP
    _SEP: (_ZERO, _DIGIT, _MINUS),
    _ZERO: (_SEP, _ZERO, _DIGIT, _DOT, _EXP),  # "0" then a digit at a number's start: see below
    _DIGIT: (_SEP, _ZERO, _DIGIT, _DOT, _EXP),
    _DOT: (_ZERO, _DIGIT),
    _EXP: (_ZERO, _DIGIT, _PLUS, _MINUS),
    _PLUS: (_ZERO, _DIGIT),
    _MINUS: (_ZERO, _DIGIT),
}
_PAIR_OK = np.zeros(64, bool)
for _first, _nexts in _FOLLOWS.items():
    _PAIR_OK[[8 * _first + _next for _next in _nexts]] = True


def _plain_json_numbers(text: np.ndarray) -> bool:
    """Whether ``text`` is numbers in JSON's grammar, separated by single ",".

    Every pair of neighbouring bytes must be allowed by ``_FOLLOWS``; that
    leaves a number's leading zero ("01", "-01"), checked apart, and two dots
    or exponents in one number, which Arrow's CSV reader refuses.
    """
    classes = np.empty(text.size + 2, np.uint8)
    classes[0] = classes[-1] = _SEP
    _CLASS.take(text, out=classes[1:-1])
    pairs = classes[:-1] * np.uint8(8)
    pairs += classes[1:]
    if not np.all(_PAIR_OK.take(pairs)):
        return False
    digits = (_ZERO, _DIGIT)
    at = np.flatnonzero(pairs == 8 * _SEP + _ZERO) + 2  # the byte after a leading "0"
    if np.any(np.isin(classes[at], digits)):
        return False
    at = np.flatnonzero(pairs == 8 * _SEP + _MINUS) + 2  # the byte after a leading "-"
    at = at[classes[at] == _ZERO] + 1
    return not np.any(np.isin(classes[at], digits))


def _stamps(text: np.ndarray, digits: np.ndarray) -> np.ndarray | None:
    """The stamps (plain JSON integers ``0`` or ``[1-9][0-9]*``) as int64, or None."""
    if np.any(text - np.uint8(_ZERO_BYTE) > 9):
        return None
    firsts = np.cumsum(digits) - digits
    if np.any((text[firsts] == _ZERO_BYTE) & (digits > 1)):
        return None
    return _cast(text, np.concatenate([[0], np.cumsum(digits)]), "int64")


def _samples(numbers: np.ndarray, ours: np.ndarray, n: int) -> np.ndarray | None:
    """``x,y,z,x,y,z,...`` as (n, 3) float64, or None if not exactly that in plain JSON."""
    comma = numbers == _COMMA
    commas = np.flatnonzero(comma)
    # three per message but the last, the third ours: so exactly three numbers each
    if commas.size != 3 * n - 1 or not np.array_equal(commas[2::3], ours):
        return None
    if not _plain_json_numbers(numbers):
        return None
    ends = np.empty(3 * n, np.int64)
    ends[:-1] = commas - np.arange(commas.size)  # in the text without the commas
    ends[-1] = numbers.size - commas.size
    values = _cast(numbers[~comma], np.concatenate([[0], ends]), "float64")
    return None if values is None else values.reshape(n, 3)


def _cast(text: np.ndarray, offsets: np.ndarray, kind: str) -> np.ndarray | None:
    """Numbers, laid end to end in ``text`` between ``offsets``, parsed by Arrow; None if refused.

    Arrow's string-to-number casts are exact for integers and correctly
    rounded for floats (the same values as :func:`json.loads`).
    """
    try:
        import pyarrow as pa
        import pyarrow.compute as pa_compute
    except ImportError:  # rerun-sdk brings pyarrow; without it the general path reads
        return None
    if offsets[-1] >= 2**31:
        return None
    strings = pa.StringArray.from_buffers(
        offsets.size - 1, pa.py_buffer(offsets.astype(np.int32)), pa.py_buffer(text)
    )
    try:
        parsed = pa_compute.cast(strings, pa.int64() if kind == "int64" else pa.float64())
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return None
    if parsed.null_count:
        return None
    return parsed.to_numpy(zero_copy_only=False).astype(kind, copy=False)
