"""What a batch imports before its sessions run: only what its workers will use.

The planner imports ``scipy.signal`` (the window search's, ≈ 0.6 s) while it hashes the
inputs, so forked workers inherit it, but only when some session has no calibration
yet (a re-run with every session up to date forks no worker).  A pipeline that
simulates nothing does not import the simulator (≈ 1 s).  Imports are per process, so
each check runs in a fresh interpreter.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

from wheelcal.batch.runner import _some_session_new


def test_some_session_new_is_whether_a_calibration_is_missing(tmp_path):
    (tmp_path / "a.calibration.json").write_text("{}")
    assert not _some_session_new(tmp_path, ["a"])
    assert _some_session_new(tmp_path, ["a", "b"])
    assert not _some_session_new(tmp_path, [])


def _fresh(code: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_plan_imports_the_window_search_for_new_sessions_only(tmp_path):
    inputs = tmp_path / "in"
    inputs.mkdir()
    for name in ("a", "b"):
        (inputs / f"{name}.mcap").write_bytes(b"not read while planning")
    pipeline = tmp_path / "p.toml"
    pipeline.write_text(
        f"[pipeline]\nname = 't'\noutput = '{tmp_path / 'out'}'\n"
        f"[inputs]\nglobs = ['{inputs}/*.mcap']\n[executor]\nworkers = 2\n"
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
    assert _fresh(code).split() == ["False", "2", "True"]
    out = tmp_path / "out"
    for name in ("a", "b"):  # calibrations present (stale: their run key differs)
        (out / f"{name}.calibration.json").write_text("{}")
    assert _fresh(code).split() == ["False", "2", "False"]


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
