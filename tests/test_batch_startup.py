"""What a batch imports before its sessions run: only what its workers will use.

The planner imports ``scipy.signal`` (the window search's, ≈ 0.6 s) while it hashes the
inputs, so forked workers inherit it, but only when some session has no calibration
yet (a re-run with every session up to date forks no worker), and only when the sessions
run in this process or in workers it forks: under ``forkserver`` the fork server preloads
it, and a worker starts with it.  A pipeline that
simulates nothing does not import the simulator (≈ 1 s).  Imports are per process, so
each check runs in a fresh interpreter.
"""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from wheelcal.batch.runner import _new_sessions
from wheelcal.batch.workers import START_METHOD_ENV

_FORKSERVER = "forkserver" in multiprocessing.get_all_start_methods()


def test_new_sessions_count_the_missing_calibrations(tmp_path):
    (tmp_path / "a.calibration.json").write_text("{}")
    assert _new_sessions(tmp_path, ["a"]) == 0
    assert _new_sessions(tmp_path, ["a", "b", "c"]) == 2
    assert _new_sessions(tmp_path, []) == 0


def _fresh(code: str, start_method: str | None = None) -> str:
    env = {**os.environ, START_METHOD_ENV: start_method or ""}
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.mark.parametrize("workers", [1, 2])
def test_plan_imports_the_window_search_for_new_sessions_only(tmp_path, workers):
    """In process (one worker) or for forked workers; the fork server's workers: see below."""
    inputs = tmp_path / "in"
    inputs.mkdir()
    for name in ("a", "b"):
        (inputs / f"{name}.mcap").write_bytes(b"not read while planning")
    pipeline = tmp_path / "p.toml"
    pipeline.write_text(
        f"[pipeline]\nname = 't'\noutput = '{tmp_path / 'out'}'\n"
        f"[inputs]\nglobs = ['{inputs}/*.mcap']\n[executor]\nworkers = {workers}\n"
    )
    code = f"""
        import sys
        from wheelcal.batch.pipeline import load_pipeline
        from wheelcal.batch.runner import _plan
        pipeline = load_pipeline({str(pipeline)!r})
        pipeline.output.mkdir(parents=True, exist_ok=True)
        before = "scipy.signal" in sys.modules
        tasks, _ = _plan(pipeline, pipeline.input_files())
        print(before, len(tasks), "scipy.signal" in sys.modules)
    """
    assert _fresh(code, "fork").split() == ["False", "2", "True"]
    # Under the fork server a planner of several workers leaves it to the server.
    expected = "True" if workers == 1 else "False"
    if _FORKSERVER:
        assert _fresh(code, "forkserver").split() == ["False", "2", expected]
    out = tmp_path / "out"
    (out / "a.calibration.json").write_text("{}")  # one new session: it runs in process
    assert _fresh(code, "forkserver" if _FORKSERVER else "fork").split() == ["False", "2", "True"]
    for name in ("a", "b"):  # calibrations present (stale: their run key differs)
        (out / f"{name}.calibration.json").write_text("{}")
    assert _fresh(code, "fork").split() == ["False", "2", "False"]


def _imported(names):
    return [name in sys.modules for name in names]


@pytest.mark.skipif(not _FORKSERVER, reason="no fork server here")
def test_a_fork_server_worker_starts_with_what_a_session_imports():
    code = """
        from concurrent.futures import ProcessPoolExecutor
        from wheelcal.batch.workers import SESSION_IMPORTS, worker_context
        from test_batch_startup import _imported
        with ProcessPoolExecutor(1, mp_context=worker_context()) as pool:
            print(*pool.submit(_imported, SESSION_IMPORTS).result())
    """
    code = f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r})\n" + textwrap.dedent(
        code
    )
    assert _fresh(code, "forkserver").split() == ["True", "True"]


def test_a_pipeline_without_simulation_does_not_import_the_simulator(tmp_path):
    pipeline = tmp_path / "p.toml"
    pipeline.write_text(
        f"[pipeline]\nname = 't'\noutput = '{tmp_path / 'out'}'\n"
        f"[inputs]\nglobs = ['{tmp_path}/*.mcap']\n"
    )
    code = f"""
        import sys
        from wheelcal.batch.pipeline import load_pipeline
        from wheelcal.batch.simulate_inputs import simulate_inputs
        made = simulate_inputs(load_pipeline({str(pipeline)!r}))
        print(len(made), "wheelcal.simulate" in sys.modules, "scipy.signal" in sys.modules)
    """
    assert _fresh(code).split() == ["0", "False", "False"]
