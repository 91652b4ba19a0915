"""The scan's strided reads of message fields against the indexed gather they replace."""

import numpy as np
import pytest

from wheelcal.io.mcap_scan import _gather_le, _gather_u64


def test_u64_gather_at_one_stride_is_the_indexed_gather():
    rng = np.random.default_rng(17)
    arr = rng.integers(0, 256, 5000, dtype=np.uint8)
    cases = [
        np.arange(3, 4000, 37),  # one stride, unaligned
        np.arange(0, 4992, 8),
        np.array([5, 100, 101, 900]),  # irregular
        np.array([7]),
        np.arange(10, 4993, 331),  # the last value ends at the buffer's last byte
    ]
    for positions in cases:
        want = arr[positions[:, None] + np.arange(8)].view("<u8").reshape(-1)
        got = _gather_u64(arr, positions)
        np.testing.assert_array_equal(got, want)
        assert got.base is None or got.base is not arr  # a copy: the chunk may be released


@pytest.mark.parametrize("dtype", ["<u2", "<u4", "<u8"])
def test_strided_reads_of_every_width_are_the_indexed_gather(dtype):
    rng = np.random.default_rng(18)
    arr = rng.integers(0, 256, 3000, dtype=np.uint8)
    size = np.dtype(dtype).itemsize
    for positions in (np.arange(1, 2900, 29), np.array([0, 3, 4, 2990]), np.array([3000 - size])):
        want = arr[positions[:, None] + np.arange(size)].view(dtype).reshape(-1)
        np.testing.assert_array_equal(_gather_le(arr, positions, dtype), want)


def test_the_scans_crc32_is_zlibs_on_whole_and_pieced_buffers(tmp_path):
    # mcap_scan takes zlib-ng's SIMD CRC-32: the checksums MCAP writers store are zlib's.
    import mmap
    import zlib

    from wheelcal.io.mcap_scan import _crc32, crc32

    rng = np.random.default_rng(5)
    data = rng.integers(0, 256, 3_000_001, dtype=np.uint8).tobytes()
    assert crc32(data) == zlib.crc32(data)
    assert crc32(data[1000:], crc32(data[:1000])) == zlib.crc32(data)
    assert crc32(b"") == 0
    path = tmp_path / "bytes"
    path.write_bytes(data)
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        assert _crc32(buf, 17, len(data) - 5) == zlib.crc32(data[17:-5])
