"""Issue 16: the CLI and the batch runner under hostile conditions.

Any exception of one session (MemoryError, RecursionError, a dying worker) is
contained and named while the others go on; devices and FIFOs are refused; a
read-only or dangling output folder is found before any work; pipeline values
are type- and range-checked; workers die with their parent; two batches on one
folder compute each session once.
"""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import wheelcal.session as session_module  # Calibration.compute calls its compute_session
from batch_inputs import pipeline_file, simulated_recordings
from wheelcal.batch.pipeline import PipelineError, load_pipeline
from wheelcal.batch.runner import run_batch
from wheelcal.cli.main import main

SRC = str(Path(__file__).resolve().parents[1] / "src")
WHEELCAL = [sys.executable, "-m", "wheelcal.cli.main"]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Three free-spin recordings (the simulate defaults)."""
    return simulated_recordings(tmp_path_factory.mktemp("inputs"), ["r0", "r1", "r2"], seed=40)


def _pipeline(tmp_path, globs, workers=1, extra=""):
    return pipeline_file(tmp_path / "p.toml", tmp_path / "out", globs, workers, extra)


def _blow_up_on(monkeypatch, name, exc):
    """Make reading one recording raise ``exc`` (the rest are read as usual)."""
    real = session_module.compute_session

    def compute(path, options):
        if Path(path).name == name:
            if exc == "exit":
                os._exit(9)  # a worker killed outright (the OOM killer)
            raise exc
        return real(path, options)

    monkeypatch.setattr(session_module, "compute_session", compute)
    # The patch reaches pool workers only through fork (forkserver and spawn import afresh).
    monkeypatch.setenv("WHEELCAL_START_METHOD", "fork")


@pytest.mark.parametrize("exc", [MemoryError(), RecursionError("maximum recursion depth")])
def test_calibrate_names_the_file_that_exhausted_memory_and_goes_on(
    tmp_path, inputs, monkeypatch, capsys, exc
):
    _blow_up_on(monkeypatch, "r0.mcap", exc)
    out = tmp_path / "out"
    status = main(
        ["calibrate", str(inputs / "r0.mcap"), str(inputs / "r1.mcap"), "--out", str(out)]
    )
    err = capsys.readouterr().err
    assert status == 1
    assert "r0.mcap" in err and type(exc).__name__ in err and "Traceback" not in err
    assert "1 of 2 recording(s) failed" in err
    assert sorted(p.name for p in out.iterdir()) == ["r1.calibration.json"]


def test_diagnose_and_apply_contain_a_memory_error(tmp_path, inputs, monkeypatch, capsys):
    out = tmp_path / "out"
    assert main(["calibrate", str(inputs / "r1.mcap"), "--out", str(out), "--quiet"]) == 0
    _blow_up_on(monkeypatch, "r0.mcap", MemoryError())
    status = main(["diagnose", str(inputs / "r0.mcap"), "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert status == 1 and "r0.mcap" in err and "MemoryError" in err
    import wheelcal.calibration.apply as apply_module

    def no_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(apply_module, "read_recording", no_memory)
    cal = out / "r1.calibration.json"
    status = main(["apply", str(cal), str(inputs / "r2.mcap"), str(tmp_path / "a.mcap")])
    err = capsys.readouterr().err
    assert status == 1 and "r2.mcap" in err and "MemoryError" in err
    assert not (tmp_path / "a.mcap").exists()


@pytest.mark.parametrize("workers", [1, 2])
def test_batch_contains_any_exception_in_every_executor(tmp_path, inputs, monkeypatch, workers):
    _blow_up_on(monkeypatch, "r1.mcap", RecursionError("maximum recursion depth exceeded"))
    outcome = run_batch(load_pipeline(_pipeline(tmp_path, f"{inputs}/*.mcap", workers)))
    assert [r.stem for r in outcome.failed] == ["r1"]
    assert "r1.mcap" in outcome.failed[0].error and "RecursionError" in outcome.failed[0].error
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["sessions"] == 3 and report["calibrated"] == 2


def test_a_worker_that_dies_fails_only_its_own_session(tmp_path, inputs, monkeypatch):
    _blow_up_on(monkeypatch, "r0.mcap", "exit")
    outcome = run_batch(load_pipeline(_pipeline(tmp_path, f"{inputs}/*.mcap", workers=2)))
    assert [r.stem for r in outcome.failed] == ["r0"], [r.error for r in outcome.records]
    assert "worker process died" in outcome.failed[0].error
    assert sorted(r.stem for r in outcome.records if r.ok) == ["r1", "r2"]


def test_devices_and_fifos_are_refused_without_reading_them(tmp_path, inputs):
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    out = tmp_path / "out"
    # In a subprocess with a timeout: reading a FIFO with no writer blocks forever.
    proc = subprocess.run(
        [
            *WHEELCAL,
            "calibrate",
            "/dev/zero",
            str(fifo),
            str(inputs / "r2.mcap"),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": SRC},
    )
    assert proc.returncode == 1, proc.stderr
    assert "/dev/zero: is a device" in proc.stderr
    assert "pipe.mcap: is a FIFO" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["r2.calibration.json"]


@pytest.mark.parametrize(
    ("section", "line", "shown"),
    [
        ("executor", 'workers = "two"', 'workers = "two"'),
        ("executor", "workers = 1.5", "workers = 1.5"),
        ("executor", "workers = 0", "workers = 0"),
        ("simulate", 'count = "3"', 'count = "3"'),
        ("simulate", "count = 1e9", "count = 1000000000.0"),
        ("simulate", "count = 1000000000", "count = 1000000000"),
        ("inputs", "globs = 5", "globs = 5"),
        ("pipeline", "output = 5", "output = 5"),
        ("run", 'rerun = "false"', 'rerun = "false"'),
        ("run", 'diagnose = "no"', 'diagnose = "no"'),
        ("run", "alpha = -1", "alpha = -1"),
        ("run", "alpha = 2", "alpha = 2"),
        ("run", 'geometry = "round"', 'geometry = "round"'),
        ("gates", "gain_tolerance = -0.1", "gain_tolerance = -0.1"),
        ("gates", 'gain_range = ["a", 2]', "gain_range = ['a', 2]"),
        ("defaults", 'radius_m = "0.28"', 'radius_m = "0.28"'),
        ("overrides", "sensor_id = 7", "sensor_id = 7"),
        ("simulate", "quantise = 1", "quantise = 1"),
    ],
)
def test_pipeline_values_of_the_wrong_type_or_range_are_usage_errors(
    tmp_path, capsys, section, line, shown
):
    body = {"pipeline": 'name = "x"', "inputs": f'globs = ["{tmp_path}/*.mcap"]'}
    key = line.split("=")[0].strip()
    kept = [ln for ln in body.get(section, "").splitlines() if not ln.startswith(key)]
    body[section] = "\n".join([*kept, line])
    path = tmp_path / "bad.toml"
    path.write_text("".join(f"[{s}]\n{text}\n" for s, text in body.items()))
    with pytest.raises(PipelineError) as exc:
        load_pipeline(path)
    message = str(exc.value)
    assert "bad.toml" in message and f"[{section}] {shown} is not allowed: use " in message
    assert main(["batch", str(path)]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_pipeline_booleans_and_unknown_keys(tmp_path):
    path = tmp_path / "ok.toml"
    path.write_text(
        f'[inputs]\nglobs = "{tmp_path}/*.mcap"\n[run]\nrerun = false\ndiagnose = false\n'
        "[executor]\nworkers = 1\n"
    )
    pipeline = load_pipeline(path)
    assert pipeline.rerun is False and pipeline.diagnose is False
    for section in ("executor", "simulate", "gates", "defaults"):
        path.write_text(f'[inputs]\nglobs = "x"\n[{section}]\nbogus = 1\n')
        with pytest.raises(PipelineError, match=rf"unknown key\(s\) \['bogus'\] in \[{section}\]"):
            load_pipeline(path)


def test_a_folder_given_as_pipeline_or_recording_is_a_usage_error(tmp_path, inputs, capsys):
    assert main(["batch", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path}: is a folder" in err and "Errno" not in err
    out = tmp_path / "out"
    assert main(["calibrate", str(inputs / "r2.mcap"), "--out", str(out), "--quiet"]) == 0
    cal = out / "r2.calibration.json"
    for args in (
        [str(cal), str(tmp_path), str(tmp_path / "x.mcap")],
        [str(tmp_path), str(inputs / "r2.mcap"), str(tmp_path / "x.mcap")],
        [str(cal), str(inputs / "r2.mcap"), str(tmp_path)],
    ):
        assert main(["apply", *args]) == 2
        err = capsys.readouterr().err
        assert str(tmp_path) in err and "is a folder" in err, err
        assert "Errno" not in err


def test_a_dangling_out_symlink_is_named(tmp_path, inputs, capsys):
    link = tmp_path / "out"
    link.symlink_to(tmp_path / "gone")
    assert main(["calibrate", str(inputs / "r2.mcap"), "--out", str(link)]) == 2
    err = capsys.readouterr().err
    assert f"{link} is a symbolic link to {tmp_path / 'gone'}, which does not exist" in err
    assert "Errno" not in err


def _read_only(monkeypatch, folder):
    """Make ``folder`` unwritable (chmod; emulated for root, which ignores the mode)."""
    folder.mkdir(exist_ok=True)
    folder.chmod(0o555)
    if os.geteuid() == 0:
        import wheelcal.io.atomic as atomic

        real = atomic.tempfile.mkstemp

        def mkstemp(*args, dir=None, **kwargs):
            if dir is not None and Path(dir).resolve() == folder.resolve():
                raise PermissionError(13, "Permission denied")
            return real(*args, dir=dir, **kwargs)

        monkeypatch.setattr(atomic.tempfile, "mkstemp", mkstemp)


def test_a_read_only_output_folder_is_found_before_any_session(
    tmp_path, inputs, monkeypatch, capsys
):
    out = tmp_path / "out"
    _read_only(monkeypatch, out)
    computed = []
    real = session_module.compute_session
    monkeypatch.setattr(
        session_module, "compute_session", lambda *a: computed.append(a) or real(*a)
    )
    status = main(["calibrate", str(inputs / "r0.mcap"), "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 2 and f"cannot write in the --out folder {out}" in err
    assert computed == [] and ".tmp" not in err
    assert main(["batch", str(_pipeline(tmp_path, f"{inputs}/*.mcap"))]) == 2
    err = capsys.readouterr().err
    assert f"cannot write in the output folder {out}" in err and computed == []
    out.chmod(0o755)


def test_an_unreadable_input_leaves_its_old_results_stale(tmp_path, inputs, monkeypatch):
    pipeline = load_pipeline(
        _pipeline(tmp_path, f"{inputs}/r2.mcap", extra="[run]\nrerun = true\n")
    )
    assert not run_batch(pipeline).failed
    out = tmp_path / "out"
    import wheelcal.batch.runner as runner

    def unreadable(path):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(runner, "file_sha256", unreadable)
    outcome = run_batch(pipeline)
    (failed,) = outcome.failed
    assert "cannot read" in failed.error and "r2.mcap" in failed.error
    assert "r2.calibration.stale.json" in failed.error and "r2.stale.rrd" in failed.error
    assert not (out / "r2.calibration.json").exists() and not (out / "r2.rrd").exists()
    assert (out / "r2.calibration.stale.json").exists() and (out / "r2.stale.rrd").exists()


def test_apply_needs_no_spin(tmp_path, inputs):
    out = tmp_path / "out"
    assert main(["calibrate", str(inputs / "r2.mcap"), "--out", str(out), "--quiet"]) == 0
    from wheelcal.io import read_recording, write_recording
    from wheelcal.recording.samples import InputPolicy

    recording = read_recording(inputs / "r2.mcap")
    short = recording.window(0.0, 3.0)  # 3 s: far too short to calibrate, fine to correct
    write_recording(short, tmp_path / "short.mcap")
    dest = tmp_path / "short-cal.mcap"
    status = main(
        ["apply", str(out / "r2.calibration.json"), str(tmp_path / "short.mcap"), str(dest)]
    )
    assert status == 0
    copy = read_recording(
        dest, topic=f"{recording.topic}/calibrated", policy=InputPolicy(min_duration_s=0.0)
    )
    assert copy.samples == short.samples


def test_dask_without_the_extra_says_what_to_install(tmp_path, inputs, monkeypatch, capsys):
    for name in ("dask", "dask.distributed", "distributed"):
        monkeypatch.setitem(sys.modules, name, None)  # "not installed"
    path = _pipeline(tmp_path, f"{inputs}/*.mcap")
    path.write_text(
        path.read_text().replace("workers = 1", 'kind = "dask"\naddress = "tcp://127.0.0.1:1"')
    )
    assert main(["batch", str(path)]) == 2
    err = capsys.readouterr().err
    assert "pip install 'wheelcal[dask]'" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "report.json").exists()


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _descendants(pid: int) -> list[int]:
    found, frontier = [], [pid]
    while frontier:
        children = [c for p in frontier for c in _children(p)]
        found += children
        frontier = children
    return found


def _pool_workers(pid: int) -> list[int]:
    """The batch's pool workers: descendants with no children of their own, past the helpers."""
    workers = []
    for p in _descendants(pid):
        try:
            cmdline = Path(f"/proc/{p}/cmdline").read_bytes()
        except OSError:
            continue
        if b"resource_tracker" not in cmdline and not _children(p) and _alive(p):
            workers.append(p)
    return workers


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
@pytest.mark.parametrize("method", ["fork", "forkserver", "spawn"])
def test_workers_exit_when_the_batch_parent_is_killed(tmp_path, inputs, method):
    # Under forkserver a worker's parent is the fork server, not the batch (issue 28).
    path = _pipeline(tmp_path, f"{inputs}/*.mcap", workers=2)
    proc = subprocess.Popen(
        [*WHEELCAL, "batch", str(path)],
        env={**os.environ, "PYTHONPATH": SRC, "WHEELCAL_START_METHOD": method},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        workers = []
        while time.monotonic() < deadline and len(workers) < 2:
            time.sleep(0.1)
            workers = _pool_workers(proc.pid)
        assert len(workers) == 2, "the batch did not start its two workers"
        everything = _descendants(proc.pid)
        time.sleep(0.5)  # inside their first sessions
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and any(map(_alive, everything)):
            time.sleep(0.1)
        left = [p for p in everything if _alive(p)]
    finally:
        proc.kill()
    for pid in left:  # do not leave them to the next test
        os.kill(pid, signal.SIGKILL)
    assert left == [], "orphaned workers survived their parent"


def test_two_batches_on_one_folder_compute_each_session_once(tmp_path, inputs):
    path = _pipeline(tmp_path, f"{inputs}/*.mcap", workers=1)
    command = [*WHEELCAL, "batch", str(path)]
    env = {**os.environ, "PYTHONPATH": SRC}
    runs = [
        subprocess.Popen(
            command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        for _ in range(2)
    ]
    results = [run.communicate(timeout=300) for run in runs]
    assert [run.returncode for run in runs] == [0, 0], results
    fitted = [
        Path(m.group(1)).name for _, err in results for m in re.finditer(r"\] ok (\S+) \(fit ", err)
    ]
    assert sorted(fitted) == ["r0.mcap", "r1.mcap", "r2.mcap"], results
    for out, _ in results:
        assert "3 sessions: 3 calibrated" in out
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["sessions"] == 3 and report["calibrated"] == 3 and not report["failed"]
    assert all(s["status"] in ("calibrated", "up to date") for s in report["per_session"])


def test_a_fifo_matched_by_the_globs_is_a_named_failure(tmp_path, inputs):
    folder = tmp_path / "rec"
    folder.mkdir()
    (folder / "r2.mcap").write_bytes((inputs / "r2.mcap").read_bytes())
    os.mkfifo(folder / "live.mcap")  # a logger's pipe: reading it would block forever
    (folder / "sub.mcap").mkdir()  # a folder the glob matches is simply not a recording
    outcome = run_batch(load_pipeline(_pipeline(tmp_path, f"{folder}/*.mcap")))
    assert [r.stem for r in outcome.records] == ["live", "r2"]
    (failed,) = outcome.failed
    assert "live.mcap: is a FIFO (named pipe), not a recording file" in failed.error


def test_a_failed_write_names_the_file_not_the_hidden_temporary(tmp_path, monkeypatch):
    import wheelcal.io.atomic as atomic

    def mkstemp(prefix="", suffix="", dir=None):
        raise PermissionError(13, "Permission denied", str(Path(dir) / f"{prefix}x{suffix}"))

    monkeypatch.setattr(atomic.tempfile, "mkstemp", mkstemp)
    target = tmp_path / "r.calibration.json"
    with pytest.raises(PermissionError) as exc:
        atomic.atomic_write_text(target, "{}")
    assert str(target) in str(exc.value) and ".tmp" not in str(exc.value)


def test_writing_onto_a_folder_names_it_not_a_temporary(tmp_path, inputs, capsys):
    out = tmp_path / "out"
    assert main(["calibrate", str(inputs / "r2.mcap"), "--out", str(out), "--quiet"]) == 0
    cal = str(out / "r2.calibration.json")
    assert main(["export", cal, "--format", "yaml", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"--out {tmp_path} is a folder" in err and ".tmp" not in err and "Errno" not in err
    from wheelcal.io.atomic import atomic_write_text

    with pytest.raises(IsADirectoryError) as exc:
        atomic_write_text(tmp_path, "x")
    assert exc.value.filename == str(tmp_path) and ".tmp" not in str(exc.value)
