"""The one-sample-per-message JSON fast path against the general decoder.

The fast path (``wheelcal.io.accel_json_single``) must give the general
path's values bit for bit when it answers, and must answer ``None`` (so the
general path accepts or names the message) whenever a message is not plain
JSON of exactly its layout.  The general path is the oracle here.
"""

import json

import numpy as np
import pytest

from message_blocks import message_block
from wheelcal.io import accel_json, accel_json_single
from wheelcal.io.accel_json import AccelBatchError, decode_accel_batch, encode_accel_batches
from wheelcal.io.accel_json_single import decode_single_samples
from wheelcal.io.mcap_scan import MessageBlock


def _block(payloads, rng):
    """The payloads as in a chunk, random bytes (often "," or "]") between."""
    return message_block(payloads, rng, b",]\n[0-.e")


def _payloads(rng, n=40):
    stamps = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000
    accel = rng.normal(0.0, 20.0, (n, 3)) * 10.0 ** rng.integers(-6, 6, (n, 3))
    return [payload for _, payload in encode_accel_batches(stamps, accel, 1)]


def _general(block, monkeypatch):
    """What the general path makes of the block: arrays, or the error's text."""
    with monkeypatch.context() as m:
        m.setattr(accel_json, "decode_single_samples", lambda block: None)
        try:
            out = decode_accel_batch((block,))
        except AccelBatchError as exc:
            return str(exc)
    return out


def test_plain_messages_take_the_fast_path_with_the_general_paths_values(monkeypatch):
    rng = np.random.default_rng(3)
    payloads = _payloads(rng, 500)
    block = _block(payloads, rng)
    fast = decode_single_samples(block)
    assert fast is not None
    want = [json.loads(p) for p in payloads]
    np.testing.assert_array_equal(fast[0], [m["timestamps_ns"][0] for m in want])
    assert fast[0].dtype == np.int64
    np.testing.assert_array_equal(fast[1], [m["accel"][0] for m in want])
    general = _general(block, monkeypatch)
    np.testing.assert_array_equal(fast[0], general.time_ns)
    np.testing.assert_array_equal(fast[1], general.accel)
    one = _block(payloads[:1], rng)  # a block of a single message
    np.testing.assert_array_equal(decode_single_samples(one)[1], fast[1][:1])


# spellings of the second number of message 7; True: plain JSON (the fast path must take it)
SPELLINGS = {
    "0": True,
    "-0": True,
    "0.5": True,
    "-0.25": True,
    "10": True,
    "1e5": True,
    "1E+5": True,
    "1e-05": True,
    "-1.5e-300": True,
    "1e400": True,  # beyond float64: inf from both paths
    "123456789012345678901234567890": True,
    ".5": False,
    "5.": False,
    "+5": False,
    "01": False,
    "-01": False,
    "00": False,
    "1.e5": False,
    "1e": False,
    "1e+": False,
    "-": False,
    "--1": False,
    "1-2": False,
    "1.2.3": False,
    "1e2e3": False,
    "1e2.5": False,
    "inf": False,
    "nan": False,
    "NaN": False,
    " 1": False,
    "1 ": False,
    "": False,
    "0x10": False,
    "1,2": False,  # four numbers in the row
    '"1"': False,
    "null": False,
    "true": False,
}


@pytest.mark.parametrize("spelling", sorted(SPELLINGS))
def test_a_number_spelling_is_taken_only_if_plain_json(spelling, monkeypatch):
    rng = np.random.default_rng(5)
    payloads = _payloads(rng)
    message = json.loads(payloads[7])
    accel = message["accel"][0]
    payloads[7] = (
        f'{{"timestamps_ns":[{message["timestamps_ns"][0]}],'
        f'"accel":[[{accel[0]!r},{spelling},{accel[2]!r}]]}}'
    ).encode()
    block = _block(payloads, rng)
    fast = decode_single_samples(block)
    general = _general(block, monkeypatch)
    assert (fast is not None) == SPELLINGS[spelling]
    if fast is not None:
        np.testing.assert_array_equal(fast[1], general.accel)
        np.testing.assert_array_equal(fast[0], general.time_ns)
    if isinstance(general, str):
        with pytest.raises(AccelBatchError) as caught:
            decode_accel_batch((block,))
        assert str(caught.value) == general  # the same words as without the fast path
    else:
        np.testing.assert_array_equal(decode_accel_batch((block,)).accel, general.accel)


STAMPS = {
    "0": True,
    "7": True,
    "1700000000000000000": True,
    "-5": False,  # plain JSON, but left to the general path
    "05": False,
    "1.5": False,
    "1e18": False,
    "99999999999999999999": False,  # beyond int64
    "": False,
    "1,2": False,  # two stamps, one row
}


@pytest.mark.parametrize("stamp", sorted(STAMPS))
def test_a_stamp_spelling_is_taken_only_if_a_plain_json_integer(stamp, monkeypatch):
    rng = np.random.default_rng(6)
    payloads = _payloads(rng)
    payloads[3] = f'{{"timestamps_ns":[{stamp}],"accel":[[1.0,2.0,3.0]]}}'.encode()
    block = _block(payloads, rng)
    fast = decode_single_samples(block)
    assert (fast is not None) == STAMPS[stamp]
    general = _general(block, monkeypatch)
    if fast is not None:
        np.testing.assert_array_equal(fast[0], general.time_ns)
        assert fast[0][3] == int(stamp)
    elif isinstance(general, str):
        with pytest.raises(AccelBatchError) as caught:
            decode_accel_batch((block,))
        assert str(caught.value) == general


@pytest.mark.parametrize(
    "payload",
    [
        b'{"accel":[[1.0,2.0,3.0]],"timestamps_ns":[5]}',  # other key order
        b'{"timestamps_ns": [5], "accel": [[1.0, 2.0, 3.0]]}',  # blanks
        b'{"timestamps_ns":[5],"accel":[[1.0,2.0,3.0]],"temperature_c":[20.0]}',
        b'{"timestamps_ns":[5],"accel":[[1.0,2.0,3.0]],"gyro":[[0.1,0.2,0.3]]}',
        b'{"timestamps_ns":[5,6],"accel":[[1.0,2.0,3.0],[4.0,5.0,6.0]]}',  # two samples
        b'{"timestamps_ns":[5],"accel":[[1.0,2.0]]}',
        b'{"timestamps_ns":[5],"accel":[[1.0,2.0,3.0,4.0]]}',
        b'{"timestamps_ns":[5],"accel":[[1.0,2.0,3.0]]}\n',
        b'{"timestamps_ns":[5],"acce1":[[1.0,2.0,3.0]]}',
        b'{"timestamps_ns":[5],"accel":[[1.0,2.0,3.0]]]',
        b'{"timestamps_ns":[5],"accel":[[1.0,2.0,3.0]}',  # one "]" short
        b'{"timestamps_ns":[5],"accel":[[1.0,2.0,3.0}}',
        b'{"timestamps_ns":[5],"accel":[[1.0,2\xff,3.0]]}',
        b'{"timestamps_ns":[5]],"accel":[[1.0,2.0,3.0]]}',
        # a "]" where a 19-digit stamp's would be, after a short stamp and two numbers
        b'{"timestamps_ns":[5],"accel":[[1.0,2]]}',
    ],
)
def test_any_other_message_layout_goes_to_the_general_path(payload, monkeypatch):
    rng = np.random.default_rng(7)
    payloads = _payloads(rng)
    payloads[11] = payload
    block = _block(payloads, rng)
    assert decode_single_samples(block) is None
    general = _general(block, monkeypatch)
    if isinstance(general, str):
        with pytest.raises(AccelBatchError) as caught:
            decode_accel_batch((block,))
        assert str(caught.value) == general


def test_messages_not_back_to_back_go_to_the_general_path():
    rng = np.random.default_rng(8)
    block = _block(_payloads(rng), rng)
    offsets = block.payload_offsets.copy()
    shifted = MessageBlock(
        block.buffer, offsets[::2], block.payload_lengths[::2], block.log_time_ns[::2]
    )
    assert decode_single_samples(shifted) is None
    assert decode_accel_batch((shifted,)).time_ns.size == offsets[::2].size


def test_a_long_first_stamp_and_a_short_last_message_are_no_trouble(monkeypatch):
    rng = np.random.default_rng(9)
    payloads = _payloads(rng)
    payloads[0] = b'{"timestamps_ns":[' + b"1" * 100 + b'],"accel":[[1.0,2.0,3.0]]}'
    payloads[-1] = b'{"timestamps_ns":[5],"accel":[[1,2,3]]}'
    block = _block(payloads, rng)
    assert decode_single_samples(block) is None
    with pytest.raises(AccelBatchError) as caught:
        decode_accel_batch((block,))
    assert str(caught.value) == _general(block, monkeypatch)


def test_random_damage_never_escapes_as_another_error_and_never_changes_a_value(monkeypatch):
    """Flipped, dropped and inserted bytes: the fast path answers the general path's values or
    None, and never raises."""
    rng = np.random.default_rng(10)
    alphabet = np.frombuffer(b'0123456789.,-+eE[]{}":x \n\xff', np.uint8)
    taken = 0
    for _ in range(300):
        payloads = _payloads(rng, 12)
        for _ in range(rng.integers(1, 4)):
            i = int(rng.integers(len(payloads)))
            data = bytearray(payloads[i])
            at = int(rng.integers(len(data)))
            kind = rng.integers(3)
            if kind == 0:
                data[at] = int(rng.choice(alphabet))
            elif kind == 1:
                del data[at]
            else:
                data.insert(at, int(rng.choice(alphabet)))
            payloads[i] = bytes(data)
        block = _block(payloads, rng)
        fast = decode_single_samples(block)
        if fast is not None:
            taken += 1
            general = _general(block, monkeypatch)
            np.testing.assert_array_equal(fast[0], general.time_ns)
            np.testing.assert_array_equal(fast[1], general.accel)
    assert 0 < taken < 300  # some damage leaves plain JSON (a digit for a digit), most does not


def _plain_json_numbers_by_table(text: bytes) -> bool:
    """The grammar check the straightforward way: byte classes and allowed pairs by table."""
    single = accel_json_single
    classes = single._CLASS[np.frombuffer(b"," + text + b",", np.uint8)].astype(np.int64)
    if not np.all(single._PAIR_OK[8 * classes[:-1] + classes[1:]]):
        return False
    numbers = text.split(b",")
    return not any(
        len(body) > 1 and body[0] == ord("0") and chr(body[1]).isdigit()
        for body in (number.removeprefix(b"-") for number in numbers)
    )


def test_the_grammar_comparisons_are_the_table_of_allowed_pairs():
    rng = np.random.default_rng(12)
    alphabet = np.frombuffer(b"0123456789.,-+eEx ", np.uint8)
    pieces = [b"0", b"-0", b"01", b"-01", b"1.5", b"1e5", b"1E+5", b"-2.5e-3", b"00", b"10"]
    agree = {True: 0, False: 0}
    for _ in range(3000):
        if rng.random() < 0.5:  # numbers, mostly plain
            text = b",".join(pieces[i] for i in rng.integers(len(pieces), size=rng.integers(1, 6)))
        else:  # anything
            text = rng.choice(alphabet, int(rng.integers(1, 12))).tobytes()
        want = _plain_json_numbers_by_table(text)
        assert accel_json_single._plain_json_numbers(np.frombuffer(text, np.uint8)) == want, text
        agree[want] += 1
    assert min(agree.values()) > 300  # both answers well exercised


def test_uniform_stamps_are_pythons_integers():
    rng = np.random.default_rng(13)
    for width in (1, 2, 18, 19):
        texts = [
            "".join(map(str, rng.integers(0, 10, width))).lstrip("0").rjust(width, "1")
            for _ in range(200)
        ]
        digits = np.frombuffer("".join(texts).encode(), np.uint8).reshape(-1, width)
        got = accel_json_single._uniform_stamps(digits)
        if width == 19 and any(int(t) >= 2**63 for t in texts):
            assert got is None  # beyond int64: the general path words it
        else:
            assert got.dtype == np.int64
            assert got.tolist() == [int(t) for t in texts]
    top = np.frombuffer(str(2**63 - 1).encode(), np.uint8).reshape(1, 19)
    assert accel_json_single._uniform_stamps(top).tolist() == [2**63 - 1]
    over = np.frombuffer(str(2**63).encode(), np.uint8).reshape(1, 19)
    assert accel_json_single._uniform_stamps(over) is None
    leading_zero = np.frombuffer(b"1005", np.uint8).reshape(2, 2)  # "05" is no JSON integer
    assert accel_json_single._uniform_stamps(leading_zero) is None
    zeros = np.frombuffer(b"00", np.uint8).reshape(2, 1)  # but "0" is
    assert accel_json_single._uniform_stamps(zeros).tolist() == [0, 0]


def test_blocks_of_one_stamp_width_read_as_by_the_labelled_path(monkeypatch):
    """The uniform-width path (windows, blanks) and the labelled one agree, also on damage."""
    rng = np.random.default_rng(14)
    alphabet = np.frombuffer(b'0123456789.,-+eE[]{}":x \n\xff', np.uint8)
    uniform = 0
    for trial in range(300):
        payloads = _payloads(rng, 12)
        for _ in range(rng.integers(0, 3) if trial % 3 else 0):
            i = int(rng.integers(len(payloads)))
            data = bytearray(payloads[i])
            data[int(rng.integers(len(data)))] = int(rng.choice(alphabet))
            payloads[i] = bytes(data)
        block = _block(payloads, rng)
        fast = decode_single_samples(block)
        with monkeypatch.context() as m:
            m.setattr(accel_json_single, "_MAX_STAMP_DIGITS", 0)  # always the labelled path
            labelled = decode_single_samples(block)
        assert (fast is None) == (labelled is None)
        if fast is not None:
            uniform += 1
            np.testing.assert_array_equal(fast[0], labelled[0])
            np.testing.assert_array_equal(fast[1], labelled[1])
    assert uniform > 100
