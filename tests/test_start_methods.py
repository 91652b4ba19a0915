"""Issue 28: batch workers under every start method (fork, spawn, forkserver).

Python 3.14 starts pool workers through a fork server by default; there a
worker's parent is the server, not the batch.  The parent-death check must
follow the batch itself, and the batch must calibrate under each method.
"""

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

import pytest

from batch_inputs import pipeline_file, simulated_recordings
from wheelcal.batch.pipeline import load_pipeline
from wheelcal.batch.runner import run_batch
from wheelcal.batch.workers import START_METHOD_ENV, exit_with_parent, start_method

_AVAILABLE = multiprocessing.get_all_start_methods()
METHODS = [m for m in ("fork", "spawn", "forkserver") if m in _AVAILABLE]


@pytest.mark.parametrize("method", METHODS)
def test_a_worker_guarded_by_the_batch_pid_runs_under_every_start_method(method):
    context = multiprocessing.get_context(method)
    with ProcessPoolExecutor(
        2, mp_context=context, initializer=exit_with_parent, initargs=(os.getpid(),)
    ) as pool:
        pids = set(pool.map(_pid, range(4)))
    assert pids and os.getpid() not in pids


def _pid(_):
    return os.getpid()


def test_the_start_method_is_explicit_and_the_environment_overrides_it(monkeypatch):
    monkeypatch.delenv(START_METHOD_ENV, raising=False)
    expected = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    assert start_method() == expected
    monkeypatch.setenv(START_METHOD_ENV, "spawn")
    assert start_method() == "spawn"
    monkeypatch.setenv(START_METHOD_ENV, "vfork")
    with pytest.raises(ValueError, match="WHEELCAL_START_METHOD='vfork'"):
        start_method()


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    return simulated_recordings(tmp_path_factory.mktemp("rec"), ["s0", "s1", "s2"], seed=70)


@pytest.mark.parametrize("method", METHODS)
def test_a_two_worker_batch_calibrates_every_session_under_each_start_method(
    tmp_path, recordings, monkeypatch, method
):
    monkeypatch.setenv(START_METHOD_ENV, method)
    path = pipeline_file(tmp_path / "p.toml", tmp_path / "out", f"{recordings}/*.mcap", workers=2)
    outcome = run_batch(load_pipeline(path))
    assert [r.error for r in outcome.records] == [None, None, None]
    assert sorted(p.name for p in (tmp_path / "out").glob("*.calibration.json")) == [
        "s0.calibration.json",
        "s1.calibration.json",
        "s2.calibration.json",
    ]
