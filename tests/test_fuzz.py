"""Seeded fuzzing of ``wheelcal calibrate`` with damaged MCAP files (issue 16).

Two short recordings (ROS 2 ``sensor_msgs/msg/Imu`` and the JSON
``wheelcal.AccelBatch``) are damaged in a few hundred seeded ways: byte flips,
truncations, zeroed ranges, duplicated chunks, record length fields swapped or
replaced, chunk headers claiming up to 1 TiB, and JSON nested ``[[[[…`` deep.
Half the cases damage the file (its CRCs see it); half damage the messages of
an uncompressed copy whose CRCs are set to 0 ("not computed"), which reaches
the decoders.  The damaged files are calibrated by the command line in a few
subprocesses, each under a data-segment limit (``RLIMIT_DATA``) and a timeout,
so a decompression bomb or a hang fails this test instead of the machine.
For every case:

* no Python traceback, no crash by signal, no hang;
* the case is either calibrated or named as failed, never neither;
* nothing is left over: no temporary or hidden file, no calibration of a
  failed file;
* a calibration that is written equals the undamaged file's within 5 σ per
  gain and offset (the two σ combined: damage that makes the data noisier may
  widen the σ, honestly): damage is refused or harmless, never a confident
  wrong answer.
"""

import json
import os
import re
import struct
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from wheelcal.batch.session import calibrate_session
from wheelcal.io import write_recording
from wheelcal.session.compute import SessionOptions
from wheelcal.simulate import simulate, table2
from wheelcal.simulate.simulator import Scenario

SRC = str(Path(__file__).resolve().parents[1] / "src")
SEED = int(os.environ.get("WHEELCAL_FUZZ_SEED", "16"))  # another seed explores further
CASES_PER_ENCODING = 150
GROUPS = 4  # subprocesses, two at a time (CI has 2 cores)
GROUP_TIMEOUT_S = 150.0
MEMORY_LIMIT_BYTES = 1536 * 2**20  # RLIMIT_DATA, not RLIMIT_AS (address space is cheap)
PARAMETERS = [f"gain_{a}" for a in "xyz"] + [f"offset_{a}_mps2" for a in "xyz"]
MAGIC = b"\x89MCAP0\r\n"
CHUNK_OPCODE = 0x06
FOOTER_OPCODE = 0x02
MESSAGE_OPCODE = 0x05
DATA_END_OPCODE = 0x0F
MESSAGE_HEADER_BYTES = 22  # channel id, sequence, log time, publish time


def _records(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, length) of every top-level MCAP record, up to the footer."""
    found, pos = [], len(MAGIC)
    while pos + 9 <= len(data):
        opcode = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        found.append((pos, opcode, length))
        if opcode == FOOTER_OPCODE or pos + 9 + length > len(data):
            break
        pos += 9 + length
    return found


def damage(data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    """One seeded damage of an MCAP file: (kind, damaged bytes)."""
    out = bytearray(data)
    records = _records(data)
    kind = str(rng.choice(["flip", "truncate", "zero", "dup_chunk", "length"]))
    if kind == "flip":
        for pos in rng.integers(0, len(out), size=int(rng.integers(1, 9))):
            out[pos] ^= int(rng.integers(1, 256))
    elif kind == "truncate":  # anywhere, or in the summary and footer
        tail = int(rng.integers(1, 300))
        cut = int(rng.integers(0, len(out))) if rng.random() < 0.5 else len(out) - tail
        del out[max(cut, 0) :]
    elif kind == "zero":
        start, size = int(rng.integers(0, len(out))), int(rng.integers(1, 513))
        out[start : start + size] = bytes(len(out[start : start + size]))
    elif kind == "dup_chunk":
        chunks = [r for r in records if r[1] == CHUNK_OPCODE]
        pos, _, length = chunks[int(rng.integers(0, len(chunks)))]
        record = bytes(out[pos : pos + 9 + length])
        other = chunks[int(rng.integers(0, len(chunks)))][0]
        at = pos + 9 + length if rng.random() < 0.5 else other  # next to itself, or elsewhere
        out[at:at] = record
    else:  # a record's length field swapped with another's, or replaced
        i, j = rng.choice(len(records), size=2, replace=False)
        a, b = records[int(i)], records[int(j)]
        if rng.random() < 0.5:
            struct.pack_into("<Q", out, a[0] + 1, b[2])
            struct.pack_into("<Q", out, b[0] + 1, a[2])
        else:
            huge = int(rng.choice([2**40, 2**63 - 1, a[2] + 1, max(a[2] - 1, 0), 0]))
            struct.pack_into("<Q", out, a[0] + 1, huge)
    return kind, bytes(out)


def _chunk_records(data: bytes, chunk_at: int) -> tuple[int, int]:
    """(start, end) of the records inside an uncompressed chunk."""
    body = chunk_at + 9
    (name_len,) = struct.unpack_from("<I", data, body + 28)
    (size,) = struct.unpack_from("<Q", data, body + 32 + name_len)
    start = body + 40 + name_len
    return start, start + size


def _without_crcs(data: bytes) -> bytearray:
    """A copy with every CRC set to 0, which MCAP defines as "not computed"."""
    out = bytearray(data)
    for pos, opcode, _ in _records(data):
        if opcode == CHUNK_OPCODE:
            struct.pack_into("<I", out, pos + 9 + 24, 0)  # uncompressed_crc
        elif opcode == DATA_END_OPCODE:
            struct.pack_into("<I", out, pos + 9, 0)  # data section CRC
        elif opcode == FOOTER_OPCODE:
            struct.pack_into("<I", out, pos + 9 + 16, 0)  # summary CRC
    return out


def damage_chunk_header(data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    """A compressed chunk whose header lies about its uncompressed size (a "zstd bomb").

    The CRCs are set to 0, so only the reader's own limits stand between the
    claim (up to 1 TiB) and an allocation.
    """
    out = _without_crcs(data)
    chunks = [pos for pos, opcode, _ in _records(data) if opcode == CHUNK_OPCODE]
    at = chunks[int(rng.integers(0, len(chunks)))] + 9 + 16
    (size,) = struct.unpack_from("<Q", data, at)
    claim = int(rng.choice([2**40, 2**31, size * 2, size // 2, size + 1, 0]))
    struct.pack_into("<Q", out, at, claim)
    return "chunk_size", bytes(out)


def damage_nesting(data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    """One JSON message's payload replaced by ``[[[[…`` (tens of thousands deep), CRCs 0."""
    out = _without_crcs(data)
    chunks = [pos for pos, opcode, _ in _records(data) if opcode == CHUNK_OPCODE]
    start, end = _chunk_records(data, chunks[int(rng.integers(0, len(chunks)))])
    messages, pos = [], start
    while pos + 9 <= end:
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if data[pos] == MESSAGE_OPCODE:
            messages.append((pos, length))
        pos += 9 + length
    pos, length = messages[int(rng.integers(0, len(messages)))]
    payload = pos + 9 + MESSAGE_HEADER_BYTES
    out[payload : pos + 9 + length] = b"[" * (length - MESSAGE_HEADER_BYTES)
    return "nested_json", bytes(out)


def damage_content(data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    """Damage the messages of an uncompressed file past its CRCs (set to 0: "not computed").

    This reaches the decoders (CDR, JSON, stamps, samples) with damage no CRC
    catches, as a buggy logger or a hand-edited file would.  The damage keeps
    every size, so the summary's indexes stay valid.
    """
    out = _without_crcs(data)
    records = _records(data)
    chunks = [pos for pos, opcode, _ in records if opcode == CHUNK_OPCODE]
    start, end = _chunk_records(data, chunks[int(rng.integers(0, len(chunks)))])
    inner, pos = [], start
    while pos + 9 <= end:
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        inner.append((pos, data[pos], length))
        pos += 9 + length
    messages = [r for r in inner if r[1] == MESSAGE_OPCODE]
    kind = str(rng.choice(["msg_flip", "msg_zero", "msg_copy", "msg_length"]))
    if kind == "msg_flip":
        for pos in rng.integers(start, end, size=int(rng.integers(1, 9))):
            out[pos] ^= int(rng.integers(1, 256))
    elif kind == "msg_zero":
        at, size = int(rng.integers(start, end)), int(rng.integers(1, 257))
        out[at : min(at + size, end)] = bytes(min(at + size, end) - at)
    elif kind == "msg_copy":  # one message's bytes over another of the same size
        a, b = (messages[int(k)] for k in rng.choice(len(messages), size=2, replace=False))
        if a[2] == b[2]:
            out[b[0] : b[0] + 9 + b[2]] = data[a[0] : a[0] + 9 + a[2]]
    else:
        a, b = (messages[int(k)] for k in rng.choice(len(messages), size=2, replace=False))
        struct.pack_into("<Q", out, a[0] + 1, b[2] if rng.random() < 0.5 else 2**40)
    return kind, bytes(out)


@pytest.fixture(scope="module")
def originals(tmp_path_factory):
    """The two undamaged recordings (18 s of free spin at 150 Hz) and their calibrations."""
    d = tmp_path_factory.mktemp("fuzz-originals")
    rng = np.random.default_rng(SEED)
    scenario = table2(rng=rng)
    scenario = Scenario(
        truth=scenario.truth,
        duration_s=18.0,
        rate_hz=150.0,
        noise=scenario.noise,
        info=scenario.info,
    )
    recording = simulate(scenario, rng).recording
    found = {}
    for encoding in ("ros2", "json"):
        path = d / f"{encoding}.mcap"
        write_recording(recording, path, encoding=encoding, batch_size=25)
        outcome = calibrate_session(path, SessionOptions(), d / "out")
        assert outcome.ok, outcome.error
        cal = json.loads(Path(outcome.calibration_path).read_text())
        plain = d / f"{encoding}-uncompressed.mcap"
        write_recording(recording, plain, encoding=encoding, batch_size=25, compression="none")
        found[encoding] = (path.read_bytes(), plain.read_bytes(), cal["parameters"])
    return found


def _limit_memory():
    import resource

    resource.setrlimit(resource.RLIMIT_DATA, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))


def _calibrate(files: list[Path], out: Path) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "wheelcal.cli.main", "calibrate", *map(str, files)]
    return subprocess.run(
        [*command, "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        timeout=GROUP_TIMEOUT_S,
        preexec_fn=_limit_memory,
        env={**os.environ, "PYTHONPATH": SRC, "OMP_NUM_THREADS": "1"},
    )


def test_damaged_recordings_are_refused_or_harmless(tmp_path, originals):
    rng = np.random.default_rng(SEED)
    cases: dict[str, tuple[str, str]] = {}  # file name → (encoding, kind)
    inputs = tmp_path / "in"
    inputs.mkdir()
    for encoding, (data, plain, _) in originals.items():
        for i in range(CASES_PER_ENCODING):
            # Half the cases damage the file (CRCs see it), half the messages past the CRCs.
            if i % 10 == 0:
                kind, damaged = damage_chunk_header(data, rng)
            elif i % 10 == 4 and encoding == "json":
                kind, damaged = damage_nesting(plain, rng)
            elif i % 2:
                kind, damaged = damage(data, rng)
            else:
                kind, damaged = damage_content(plain, rng)
            name = f"{encoding}-{i:03d}-{kind}.mcap"
            (inputs / name).write_bytes(damaged)
            cases[name] = (encoding, kind)
    names = sorted(cases)
    groups = [names[k::GROUPS] for k in range(GROUPS)]
    outs = [tmp_path / f"out{k}" for k in range(GROUPS)]
    with ThreadPoolExecutor(2) as pool:
        runs = list(
            pool.map(lambda k: _calibrate([inputs / n for n in groups[k]], outs[k]), range(GROUPS))
        )
    problems = []
    for group, out, run in zip(groups, outs, runs, strict=True):
        if "Traceback" in run.stderr or run.returncode not in (0, 1):
            problems.append(f"exit {run.returncode}: {run.stderr[-3000:]}")
            continue
        # The catch-alls (an exception the reader did not name, memory exhausted) are bugs.
        for line in run.stderr.splitlines():
            if "unexpected error" in line or "(MemoryError)" in line:
                problems.append(f"not a clean refusal: {line[-300:]}")
        failed = {
            Path(m.group(1)).name
            for m in re.finditer(r"^FAILED  (\S+?\.mcap)\b", run.stderr, re.MULTILINE)
        }
        written = {p.name for p in out.iterdir()} if out.exists() else set()
        leftovers = [n for n in written if n.startswith(".") or ".tmp" in n]
        if leftovers:
            problems.append(f"left over: {leftovers}")
        for name in group:
            stem = name[: -len(".mcap")]
            calibrated = f"{stem}.calibration.json" in written
            if calibrated == (name in failed):
                problems.append(
                    f"{name}: calibrated={calibrated}, named as failed={name in failed}"
                )
                continue
            if not calibrated:
                continue
            baseline = originals[cases[name][0]][2]
            got = json.loads((out / f"{stem}.calibration.json").read_text())["parameters"]
            for p in PARAMETERS:
                # Within 5 σ of the two σ combined: damage that makes the data noisier (an
                # outlier sample inflates the noise model) widens the σ, which is honest.
                delta = abs(got[p]["value"] - baseline[p]["value"])
                sigma = np.hypot(got[p]["std"], baseline[p]["std"])
                if not delta <= 5 * sigma:
                    problems.append(
                        f"{name}: {p} = {got[p]['value']} ± {got[p]['std']} vs "
                        f"{baseline[p]['value']} ± {baseline[p]['std']} (undamaged)"
                    )
    if os.environ.get("FUZZ_STATS"):  # exploring: what each kind of damage led to
        for group, out in zip(groups, outs, strict=True):
            for name in group:
                ok = (out / f"{name[:-5]}.calibration.json").exists()
                print("STAT", cases[name][1], "ok" if ok else "refused")
        for run in runs:
            for line in run.stderr.splitlines():
                if re.search(r"out of memory|unexpected error|nested too deeply|Warning", line):
                    print("NOTE", line[-300:])
    assert not problems, "\n".join(problems)
