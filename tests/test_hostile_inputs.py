"""Issue 40, item 2: every command refuses a FIFO, a device or a folder by name, unread.

Before issue 40 ``convert`` of a FIFO, ``export FIFO.json`` and ``batch FIFO.toml``
waited forever for a writer, and ``/dev/zero`` as their input was read until
memory ran out.  The cases run in one subprocess, each under an alarm and the
whole under a data-segment limit, so a regression fails here instead of hanging
the suite or exhausting the machine.  Small inputs (a pipeline, a calibration)
are read with their size checked first.
"""

import json
import os
import resource
import subprocess
import sys

import pytest

from wheelcal.batch.pipeline import PipelineError, load_pipeline
from wheelcal.calibration.session_json import CalibrationFileError, load_calibration

LIMIT_BYTES = 1536 << 20

_CASES = r"""
import contextlib, io, json, signal, sys
from wheelcal.cli.main import main

def alarm(signum, frame):
    raise TimeoutError("still reading after 10 s")

signal.signal(signal.SIGALRM, alarm)
for args in json.loads(sys.argv[1]):
    err = io.StringIO()
    signal.alarm(10)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            status = main(args)
    except BaseException as exc:
        status = f"{type(exc).__name__}: {exc}"
    finally:
        signal.alarm(0)
    print(json.dumps([status, err.getvalue()]), flush=True)
"""


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_DATA, (LIMIT_BYTES, LIMIT_BYTES))


def _run(cases: list[list[str]]) -> list[tuple[object, str]]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.run(
        [sys.executable, "-c", _CASES, json.dumps(cases)],
        capture_output=True,
        text=True,
        preexec_fn=_limit_memory,
        env=env,
        timeout=120,
    )
    lines = [json.loads(line) for line in proc.stdout.splitlines()]
    assert len(lines) == len(cases), proc.stderr[-3000:]
    return lines


def test_fifos_devices_and_folders_are_refused_by_name_before_reading(tmp_path):
    fifo = tmp_path / "live"
    os.mkfifo(fifo)
    folder = tmp_path / "folder"
    folder.mkdir()
    out = str(tmp_path / "out.mcap")
    cases = {}
    for given, kind in ((str(fifo), "a FIFO (named pipe)"), ("/dev/zero", "a device")):
        cases[f"convert {kind}"] = (
            ["convert", given, out, "--accel-unit", "m/s^2"],
            f"IN.csv {given} is {kind}",
        )
        cases[f"export {kind}"] = (
            ["export", given, "--format", "yaml"],
            f"CAL.json {given} is {kind}",
        )
        cases[f"batch {kind}"] = (["batch", given], f"{given}: is {kind}, not a file")
        cases[f"study {kind}"] = (
            ["study", "--config", given, "--out", str(tmp_path / "s")],
            f"--config {given} is {kind}",
        )
    cases["convert a folder"] = (["convert", str(folder), out], f"IN.csv {folder} is a folder")
    cases["export a folder"] = (
        ["export", str(folder), "--format", "c"],
        f"CAL.json {folder} is a folder",
    )
    cases["batch a folder"] = (["batch", str(folder)], f"{folder}: is a folder")
    said = dict(zip(cases, _run([args for args, _ in cases.values()]), strict=True))
    for name, (_, expected) in cases.items():
        status, err = said[name]
        assert status == 2, (name, status, err)
        assert expected in err, (name, err)
        assert "Traceback" not in err
    assert not os.path.exists(out)


def test_small_inputs_are_size_checked_before_they_are_read(tmp_path):
    huge = tmp_path / "huge.json"
    with open(huge, "wb") as f:
        f.truncate(100 << 20)  # sparse: 100 MiB that cost nothing to make
    with pytest.raises(
        CalibrationFileError, match=r"huge\.json: holds 104857600 bytes, more than the 64 MiB"
    ):
        load_calibration(huge)
    toml = tmp_path / "huge.toml"
    os.link(huge, toml)
    with pytest.raises(PipelineError, match=r"huge\.toml: holds 104857600 bytes"):
        load_pipeline(toml)


def test_a_calibration_nested_too_deeply_is_named(tmp_path):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 200_000)
    with pytest.raises(CalibrationFileError, match=r"deep\.json: not a calibration JSON \(nested"):
        load_calibration(deep)
