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
   layout above, and stamps and numbers are cut out in vectorised passes —
   when every stamp has the same number of digits (the common case) with
   fixed-width windows per message, the stamps' digits summed exactly in
   uint64, and what lies between two messages' numbers (one length then)
   blanked in one strided write and dropped; otherwise by labelling every
   byte of the block and three masked copies;
2. every number byte is checked to follow JSON's number grammar
   (``-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?``) with neighbour tests
   — Arrow also takes ``.5``, ``5.``, ``+5``, ``01``, ``inf``, ``nan`` and
   blanks, which JSON does not, so those are refused here; what neighbour
   tests cannot see (two dots or exponents in one number) Arrow refuses;
3. Arrow casts the numbers to float64 (and stamps of differing widths to int64).

Any deviation — another layout, a key order, white space, a ``gyro`` or
``temperature_c``, a number that is not plain JSON, a message Arrow refuses —
returns ``None``, and :func:`wheelcal.io.accel_json.decode_accel_batch` takes
its general path, which accepts what it should and names what is corrupt
exactly as before.  This path never raises for bad input.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from wheelcal.io.mcap_scan import RECORD_GAP_BYTES, MessageBlock

_PREFIX = b'{"timestamps_ns":['
_MIDDLE = b'],"accel":[['
_SUFFIX = b"]]}"
# the shortest such message: one digit for the stamp, "0,0,0" for the sample
_SHORTEST = len(_PREFIX) + 1 + len(_MIDDLE) + 5 + len(_SUFFIX)
_COMMA, _CLOSE, _ZERO_BYTE = ord(","), ord("]"), ord("0")
_GAP, _FIXED, _STAMP, _NUMBER = range(4)  # what each byte of the stretch is
_MAX_STAMP_DIGITS = 19  # below 2**64: exact in uint64 (int64's limit is checked apart)
_BLANK = ord(" ")  # fills what lies between two messages' numbers, then is dropped


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
    if lengths.min() < _SHORTEST or not block.back_to_back():
        return None
    first, last = block.span()
    stretch = np.frombuffer(block.buffer, np.uint8, count=last - first, offset=first)
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
    width = int(stamp_digits[0])
    if width <= _MAX_STAMP_DIGITS and np.all(stamp_digits == width):
        return _decode_uniform(stretch, begin, end, middle, width, number_bytes)
    return _decode_labelled(stretch, begin, end, middle, stamp_digits, number_bytes)


def blank_runs(text: np.ndarray, at: np.ndarray, width: int, head: int) -> None:
    """``text[a]`` made ``head``, the ``width - 1`` bytes after it blanks, for each ``a`` of ``at``.

    One strided write (the runs must not overlap): what lies between two
    messages' values becomes one separator and JSON white space.
    """
    sliding_window_view(text, width, writeable=True)[at] = _BLANK
    text[at] = head


def _windows(stretch: np.ndarray, at: np.ndarray, width: int) -> np.ndarray:
    """``stretch[at[i] : at[i] + width]`` for every i, as one (n, width) array."""
    return sliding_window_view(stretch, width)[at]


def _decode_uniform(
    stretch: np.ndarray,
    begin: np.ndarray,
    end: np.ndarray,
    middle: np.ndarray,
    width: int,
    number_bytes: np.ndarray,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The block whose stamps all have ``width`` digits (the common case), or None.

    The fixed text is gathered message by message in fixed-width windows;
    everything from one message's numbers to the next's — the suffix, the
    record gap, the prefix, the stamp and the middle — has then one length,
    so it is blanked in one strided write (its first byte made the ``,``
    between the messages' numbers) and dropped in one masked copy.  That no
    number byte was a blank is checked by counting what is left.
    """
    n = begin.size
    if (
        _windows(stretch, begin, len(_PREFIX)).tobytes() != _PREFIX * n
        or _windows(stretch, middle, len(_MIDDLE)).tobytes() != _MIDDLE * n
        or _windows(stretch, end - len(_SUFFIX), len(_SUFFIX)).tobytes() != _SUFFIX * n
    ):
        return None
    time_ns = _uniform_stamps(_windows(stretch, begin + len(_PREFIX), width))
    if time_ns is None:
        return None
    first = middle + len(_MIDDLE)  # each message's first number byte
    stop = end - len(_SUFFIX)  # and the byte after its last
    text = stretch[first[0] : stop[-1]].copy()
    between = len(_SUFFIX) + RECORD_GAP_BYTES + len(_PREFIX) + width + len(_MIDDLE)
    if n > 1:
        blank_runs(text, stop[:-1] - first[0], between, _COMMA)
    kept = text != _BLANK
    numbers = text[kept]
    if numbers.size != text.size - (n - 1) * (between - 1):
        return None  # a blank among the numbers: not this layout
    ours = np.cumsum(number_bytes + 1)[:-1] - 1  # where each message's "," landed
    accel = _samples(numbers, ours, n)
    if accel is None:
        return None
    return time_ns, accel


def _uniform_stamps(digits: np.ndarray) -> np.ndarray | None:
    """Stamps of (n, width) ASCII digits (plain JSON integers) as exact int64, or None."""
    values = digits - np.uint8(_ZERO_BYTE)
    if np.any(values > 9):
        return None
    if digits.shape[1] > 1 and np.any(values[:, 0] == 0):  # "05": not JSON
        return None
    out = values[:, 0].astype(np.uint64)
    ten = np.uint64(10)
    for k in range(1, digits.shape[1]):  # at most 19 digits: below 2**64, exact
        out *= ten
        out += values[:, k]
    if np.any(out > np.uint64(np.iinfo(np.int64).max)):
        return None
    return out.astype(np.int64)


def _decode_labelled(
    stretch: np.ndarray,
    begin: np.ndarray,
    end: np.ndarray,
    middle: np.ndarray,
    stamp_digits: np.ndarray,
    number_bytes: np.ndarray,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The block whose stamps differ in width: every byte labelled, the parts cut by masks."""
    n = begin.size
    # per message: prefix | stamp | middle | numbers and the suffix's "]" | rest of the suffix
    # | record gap (none after the last); the "]" becomes the "," before the next message's
    counts = np.empty((n, 6), np.int64)
    counts[:] = (len(_PREFIX), 0, len(_MIDDLE), 0, len(_SUFFIX) - 1, RECORD_GAP_BYTES)
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


# Byte classes of the number check, and which class may follow which: the grammar as a
# table (the tests' oracle for the comparisons of _plain_json_numbers).
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
    r"""Whether ``text`` (uint8) is numbers in JSON's grammar, separated by single ",".

    Every pair of neighbouring bytes must be allowed by JSON's number grammar
    (``-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?``, byte to next byte,
    ``_FOLLOWS``); that leaves a number's leading zero ("01", "-01"), checked
    apart, and two dots or exponents in one number, which Arrow refuses.

    Whole-array comparisons, no table look-ups (numpy's gathers cost ~1 ns
    per byte, its comparisons a few hundredths), mostly written in place: a
    fresh large array costs a page fault per 4 KiB, more than the comparison.
    """
    padded = np.empty(text.size + 2, np.uint8)
    padded[0] = padded[-1] = _COMMA
    padded[1:-1] = text
    sep = padded == _COMMA
    zero = padded == _ZERO_BYTE
    shifted = padded - np.uint8(_ZERO_BYTE + 1)
    digit = shifted <= 8
    digit |= zero
    sign = padded == ord("-")
    plus = padded == ord("+")
    dot = padded == ord(".")
    lower = np.bitwise_or(padded, 0x20, out=shifted)
    exp = lower == ord("e")
    here, after = slice(None, -1), slice(1, None)
    # SEP -> digit or "-"
    ok = np.bitwise_or(digit[after], sign[after])
    ok &= sep[here]
    # digit -> SEP, digit, "." or exponent
    term = np.bitwise_or(sep[after], digit[after])
    term |= dot[after]
    term |= exp[after]
    term &= digit[here]
    ok |= term
    # "." "+" "-" -> digit
    np.bitwise_or(dot[here], plus[here], out=term)
    term |= sign[here]
    term &= digit[after]
    ok |= term
    # exponent -> digit, "+" or "-"
    np.bitwise_or(digit[after], plus[after], out=term)
    term |= sign[after]
    term &= exp[here]
    ok |= term
    if not ok.all():
        return False
    # "0" then a digit at a number's start: after a separator, or after a leading "-"
    lead = np.bitwise_and(zero[1:-1], digit[2:])
    if np.any(lead & sep[:-2]):  # (the results here are all but empty: no reuse check)
        return False
    lead[1:] &= sign[1:-2]
    return not np.any(lead[1:] & sep[:-3])


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
