"""Message payloads laid out as in a decompressed MCAP chunk, for the JSON decoders' tests."""

from __future__ import annotations

import numpy as np

from wheelcal.io.mcap_scan import MessageBlock

GAP = 31  # a Message record's opcode, length and header between two payloads


def message_block(
    payloads: list[bytes], rng: np.random.Generator, gap_bytes: bytes
) -> MessageBlock:
    """The payloads back to back, GAP random bytes drawn from ``gap_bytes`` between them."""
    alphabet = np.frombuffer(gap_bytes, np.uint8)
    pieces, offsets, at = [], [], 0
    for payload in payloads:
        pieces += [rng.choice(alphabet, GAP).tobytes(), payload]
        offsets.append(at + GAP)
        at += GAP + len(payload)
    lengths = np.array([len(p) for p in payloads], np.int64)
    return MessageBlock(
        b"".join(pieces), np.array(offsets, np.int64), lengths, np.arange(len(payloads))
    )
