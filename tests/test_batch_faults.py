"""Issue 40, item 4: a batch under faults — killed, terminated, out of disk, or shared.

Before issue 40 ``kill -9`` and SIGTERM left hidden ``.sNN.rrd.XXXX.tmp`` files that
a re-run kept, SIGTERM ended the batch without a word, a full disk left
``report.md``, ``sessions.csv`` and ``overview.png`` without ``report.json`` (and a
fresh ``.rrd`` renamed ``.stale``), and two different pipelines in one folder
pooled each other's sessions.  Now: temporaries are removed when a batch starts
alone in its folder and by the writers on a signal; SIGTERM says what was done;
a full disk stops the batch with every written session complete and the report
set as it was; one folder holds one pipeline at a time.
"""

import errno
import json
import os
import re
import resource
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from batch_inputs import pipeline_file
from wheelcal.batch.locking import pipeline_lock
from wheelcal.batch.pipeline import PipelineError, load_pipeline
from wheelcal.batch.runner import _identity, run_batch
from wheelcal.batch.termination import BatchStopped
from wheelcal.viz.rrd_writer import _check_complete

SRC = str(Path(__file__).resolve().parents[1] / "src")
WHEELCAL = [sys.executable, "-m", "wheelcal.cli.main"]
ENV = {**os.environ, "PYTHONPATH": SRC}
TEMPORARY = re.compile(r"^\..+\.tmp$")


def _free_spins(folder: Path, count: int) -> Path:
    """``count`` 30 s free spins (Table II's bench): quick to fit, their .rrd ~1 MB."""
    import dataclasses

    from wheelcal.io import write_recording
    from wheelcal.simulate import preset, simulate

    for i in range(count):
        rng = np.random.default_rng([60, i])
        scenario = dataclasses.replace(preset("table2", rng=rng), duration_s=30.0)
        path = folder / f"s{i}.mcap"
        write_recording(simulate(scenario, rng, source=str(path)).recording, path)
    return folder


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Four recordings."""
    return _free_spins(tmp_path_factory.mktemp("faults"), 4)


def _pipeline(tmp_path, inputs, workers=2, rerun=True, radius=0.28, name="p.toml"):
    extra = "[run]\nrerun = true\n" if rerun else ""
    path = pipeline_file(tmp_path / name, tmp_path / "out", f"{inputs}/*.mcap", workers, extra)
    if radius != 0.28:
        path.write_text(path.read_text().replace("radius_m = 0.28", f"radius_m = {radius}"))
    return path


def _temporaries(out: Path) -> list[str]:
    return sorted(str(p.relative_to(out)) for p in out.rglob(".*") if TEMPORARY.match(p.name))


def _check_outputs(out: Path, stems) -> None:
    """Every session output complete, the report consistent with them, nothing temporary."""
    assert _temporaries(out) == []
    for stem in stems:
        doc = json.loads((out / f"{stem}.calibration.json").read_text())
        assert doc["provenance"]["run_key"]
        _check_complete(out / f"{stem}.rrd", out / f"{stem}.rrd")  # ends with its footer
    report = json.loads((out / "report.json").read_text())
    assert report["sessions"] == len(stems) and report["calibrated"] == len(stems)
    assert not report["failed"]
    assert all(Path(p).exists() for p in report["provenance"]["outputs"])


def _fitted(stderr: str) -> list[str]:
    """The recordings a run calibrated (its progress lines)."""
    return sorted(Path(m).stem for m in re.findall(r"\] ok (\S+) \(fit ", stderr))


def test_a_batch_alone_in_its_folder_removes_the_temporaries_a_killed_run_left(tmp_path, inputs):
    out = tmp_path / "out"
    (out / "sensors").mkdir(parents=True)
    left = [
        out / ".s1.rrd.x7k2abcd.tmp",
        out / ".report.json.q9w8e7r6.tmp",
        out / "sensors" / ".sim-sensor.calibration.json.abcd1234.tmp",
        out / ".wheelcal-write-test.zz9y8x7w",
    ]
    for path in left:
        path.write_bytes(b"half")
    (out / ".hidden-but-mine").write_text("kept")  # not wheelcal's pattern: left alone
    said = []
    outcome = run_batch(
        load_pipeline(_pipeline(tmp_path, inputs, workers=1, rerun=False)), said.append
    )
    assert not outcome.failed
    assert _temporaries(out) == [] and not any(p.exists() for p in left)
    assert (out / ".hidden-but-mine").read_text() == "kept"
    assert any("removed 4 temporary file(s)" in e.message for e in said)


def test_sigterm_stops_the_batch_with_a_message_and_no_temporaries(tmp_path, inputs):
    path = _pipeline(tmp_path, inputs)
    out = tmp_path / "out"
    run = subprocess.Popen(
        [*WHEELCAL, "batch", str(path)], env=ENV, stderr=subprocess.PIPE, text=True
    )
    first = run.stderr.readline()  # the first session done: the others are being written
    run.send_signal(signal.SIGTERM)
    _, rest = run.communicate(timeout=120)
    assert run.returncode == 128 + signal.SIGTERM, first + rest
    assert "stopped by SIGTERM" in rest and "their outputs are complete" in rest
    assert _temporaries(out) == []
    done = sorted(p.name.split(".")[0] for p in out.glob("*.calibration.json"))
    assert done  # the session reported before the signal is there, complete
    for stem in done:
        _check_complete(out / f"{stem}.rrd", out / f"{stem}.rrd")
    # (a re-run after a kill or a signal redoes only the missing: test_kill_9_… below)


def _limit_file_size():
    limit = 256 << 10  # every .rrd is ~1 MB: as if the disk filled up at the first
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))


def test_a_full_disk_stops_the_batch_leaving_a_consistent_folder(tmp_path, inputs):
    path = _pipeline(tmp_path, inputs, workers=1)
    out = tmp_path / "out"
    full = subprocess.run(
        [*WHEELCAL, "batch", str(path)],
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=_limit_file_size,
    )
    assert full.returncode == 1, full.stderr
    assert f"the disk of {out} is full: the batch stopped at" in full.stderr
    assert "the report was not written" in full.stderr
    assert "Traceback" not in full.stderr and "re_sdk" not in full.stderr  # no Rust log lines
    assert _temporaries(out) == []
    names = {p.name for p in out.iterdir() if not p.name.startswith(".")}
    assert not names & {"report.json", "report.md", "sessions.csv", "overview.png"}
    assert not any(".stale." in n for n in names)  # this run's files are not "earlier" ones
    assert {n for n in names if n.endswith(".rrd")} == {
        n.replace(".calibration.json", ".rrd") for n in names if n.endswith(".calibration.json")
    }
    again = subprocess.run(
        [*WHEELCAL, "batch", str(path)], env=ENV, capture_output=True, text=True, timeout=300
    )
    assert again.returncode == 0, again.stderr
    _check_outputs(out, ["s0", "s1", "s2", "s3"])


def test_a_full_disk_while_the_report_is_written_keeps_the_earlier_report(
    tmp_path, inputs, monkeypatch
):
    from wheelcal.io.atomic import StagedOutputs

    path = _pipeline(tmp_path, inputs, workers=1, rerun=False)
    out = tmp_path / "out"
    run_batch(load_pipeline(path))
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    (inputs / "extra.mcap").write_bytes((inputs / "s0.mcap").read_bytes())  # a new session
    real = StagedOutputs.write_text

    def full(self, target, text):
        if Path(target).name == "sessions.csv":
            raise OSError(errno.ENOSPC, "No space left on device", str(target))
        real(self, target, text)

    monkeypatch.setattr(StagedOutputs, "write_text", full)
    try:
        with pytest.raises(BatchStopped, match=r"the disk is full .* the report was not"):
            run_batch(load_pipeline(path))
    finally:
        (inputs / "extra.mcap").unlink()
    for name in ("report.json", "report.md", "sessions.csv", "overview.png"):
        assert (out / name).read_bytes() == before[name], name  # the earlier set, unchanged
    assert _temporaries(out) == []
    assert (out / "extra.calibration.json").exists()  # the session itself was written


def test_one_output_folder_refuses_a_second_different_pipeline(tmp_path, inputs):
    first = load_pipeline(_pipeline(tmp_path, inputs, workers=1, rerun=False))
    second = load_pipeline(
        _pipeline(tmp_path, inputs, workers=1, rerun=False, radius=0.29, name="q.toml")
    )
    (tmp_path / "out").mkdir()
    with pipeline_lock(first.output, _identity(first), "pipeline 'p', p.toml"):
        with pytest.raises(
            PipelineError,
            match=r"in use by another batch with a different "
            r"pipeline \(pipeline 'p', p.toml\)",
        ):
            run_batch(second)
        assert not list((tmp_path / "out").glob("*.calibration.json"))
        same = run_batch(first)  # the same pipeline at the same time: as before
        assert not same.failed and len(same.records) == 4
    # once the first is done the folder is free again; its report is the first's: --force
    outcome = run_batch(second, force=True)
    assert not outcome.failed


def _run_until(path: Path, after_ok: int | None, delay_s: float) -> tuple[int | None, str]:
    """Run the batch; SIGKILL it ``delay_s`` after its ``after_ok``-th session (None: from start).

    Returns the exit status (None: killed) and what it printed on stderr.
    """
    run = subprocess.Popen(
        [*WHEELCAL, "batch", str(path)],
        env=ENV,
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
    )
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(run.stderr), daemon=True)
    reader.start()
    start = time.monotonic()
    while after_ok is not None and run.poll() is None:
        if sum(" ok " in line for line in lines) >= after_ok:
            break
        if time.monotonic() - start > 120:
            break
        time.sleep(0.02)
    try:
        run.wait(timeout=delay_s)
        status = run.returncode
    except subprocess.TimeoutExpired:
        run.kill()  # SIGKILL: no chance to clean up
        run.wait()
        status = None
    reader.join(timeout=30)
    return status, "".join(lines)


def kill_and_rerun(tmp_path, inputs, kills: int, rng: np.random.Generator) -> dict:
    """``kill -9`` a batch at ``kills`` random moments, each time re-running; then finish.

    A moment is a random time after the start (0.2–4 s: reading, planning, the
    first fits) or a random delay (0–0.4 s) after a random session was
    reported (one of the first two: while the others are written).  Every run may
    compute only the sessions missing when it started; at the end no temporary
    is left and every output is valid.  Returns the figures.
    """
    path = _pipeline(tmp_path, inputs)
    out = tmp_path / "out"
    stems = sorted(p.stem for p in inputs.glob("*.mcap"))

    def missing() -> list[str]:
        return sorted(set(stems) - {p.name.split(".")[0] for p in out.glob("*.calibration.json")})

    moments, fitted_counts, left, killed = [], [], [], 0
    while killed < kills and missing():
        before = missing()
        if rng.random() < 0.7:
            after_ok = int(rng.integers(1, min(2, len(before)) + 1))
            delay = float(rng.uniform(0, 0.4))
            moments.append(f"{delay:.2f} s after session {after_ok}")
        else:
            after_ok, delay = None, float(rng.uniform(0.2, 4.0))
            moments.append(f"{delay:.2f} s")
        status, err = _run_until(path, after_ok, delay)
        killed += status is None
        fitted = _fitted(err)
        assert set(fitted) <= set(before), (moments[-1], fitted, before)
        fitted_counts.append(len(fitted))
        left.append(len(_temporaries(out)))
        time.sleep(0.3)  # its workers die with it (PR_SET_PDEATHSIG)
    before = missing()
    final = subprocess.run(
        [*WHEELCAL, "batch", str(path)], env=ENV, capture_output=True, text=True, timeout=300
    )
    assert final.returncode == 0, final.stderr
    assert _fitted(final.stderr) == before
    _check_outputs(out, stems)
    return {
        "sessions": len(stems),
        "kills": killed,
        "runs_that_finished_before_their_kill": len(moments) - killed,
        "moments": moments,
        "sessions_fitted_per_run": fitted_counts,
        "temporaries_left_by_each_kill": left,
        "missing_before_the_final_run": before,
    }


def test_kill_9_twice_then_a_rerun_finishes_cleanly(tmp_path, inputs):
    figures = kill_and_rerun(tmp_path, inputs, kills=2, rng=np.random.default_rng(7))
    print(figures)


@pytest.mark.slow
def test_kill_9_at_twenty_random_moments(tmp_path):
    folder = tmp_path / "recordings"
    folder.mkdir()
    _free_spins(folder, 80)  # enough work that 20 kills land while sessions are written
    figures = kill_and_rerun(tmp_path, folder, kills=20, rng=np.random.default_rng(2024))
    print(json.dumps(figures))
    assert figures["kills"] == 20
