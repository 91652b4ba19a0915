"""A block's payloads as newline-delimited text (for Arrow's reader) against the payloads."""

import numpy as np
import pytest

from message_blocks import GAP, message_block
from wheelcal.io import accel_json
from wheelcal.io.accel_json import decode_accel_batch, encode_accel_batches


def _block(payloads, rng):
    """The payloads as in a chunk, random bytes (often "\\n", "{") between."""
    return message_block(payloads, rng, b'\n{}[],"0 \x00\xff')


def _payloads(rng, samples, batch):
    stamps = 1_700_000_000_000_000_000 + np.arange(samples, dtype=np.int64) * 5_000_000
    accel = rng.normal(0.0, 20.0, (samples, 3))
    return [payload for _, payload in encode_accel_batches(stamps, accel, batch)]


@pytest.mark.parametrize("batch", [1, 3, 10])
def test_lines_are_the_payloads_with_white_space_between(batch):
    rng = np.random.default_rng(batch)
    payloads = _payloads(rng, 200, batch)
    lines = bytes(accel_json._lines_in_place((_block(payloads, rng),))).split(b"\n")
    assert lines[0] == payloads[0]
    assert lines[1:] == [b" " * (GAP - 1) + p for p in payloads[1:]]


@pytest.mark.parametrize("batch", [3, 10])
def test_arrow_reads_the_lines_as_json_loads_reads_the_payloads(batch, monkeypatch):
    rng = np.random.default_rng(10 + batch)
    block = _block(_payloads(rng, 500, batch), rng)
    taken = []
    arrow = accel_json._decode_with_arrow

    def recorded(*args):
        out = arrow(*args)
        taken.append(out is not None)
        return out

    monkeypatch.setattr(accel_json, "_decode_with_arrow", recorded)
    fast = decode_accel_batch((block,))
    assert taken == [True]  # Arrow read the lines
    monkeypatch.setattr(accel_json, "_decode_with_arrow", lambda *args: None)
    exact = decode_accel_batch((block,))
    np.testing.assert_array_equal(fast.time_ns, exact.time_ns)
    np.testing.assert_array_equal(fast.accel, exact.accel)
