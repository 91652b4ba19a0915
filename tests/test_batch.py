"""Batch runner end to end: report numbers, failures, re-runs, executors, pipeline errors."""

import json
import math
import re
import shutil
import textwrap
from pathlib import Path

import numpy as np
import pytest

from wheelcal.batch.pipeline import PipelineError, load_pipeline
from wheelcal.batch.runner import run_batch
from wheelcal.cli.main import main

PIPELINE = """
[pipeline]
name = "t"
output = "{out}"

[inputs]
globs = ["{inputs}/*.mcap"]

[defaults]
radius_m = 0.28

[run]
rerun = false

[executor]
{executor}
"""


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """Five Table II recordings (two mountings) and one corrupted file."""
    d = tmp_path_factory.mktemp("inputs")
    for i in range(5):
        mounting = "m1" if i < 3 else "m2"
        args = ["simulate", str(d / f"r{i}.mcap"), "--seed", str(100 + i), "--free-spin-only"]
        assert main([*args, "--mounting-id", mounting, "--sensor-id", "S1"]) == 0
    data = bytearray((d / "r0.mcap").read_bytes())
    data[len(data) // 2 : len(data) // 2 + 32] = b"\xff" * 32
    (d / "zz_corrupt.mcap").write_bytes(bytes(data))
    return d


def _pipeline(tmp_path, inputs, executor='kind = "processes"\nworkers = 2'):
    path = tmp_path / "p.toml"
    path.write_text(PIPELINE.format(out=tmp_path / "out", inputs=inputs, executor=executor))
    return load_pipeline(path)


def test_report_equals_direct_computation_and_failure_is_listed(tmp_path, recordings):
    outcome = run_batch(_pipeline(tmp_path, recordings))
    out = tmp_path / "out"
    assert len(outcome.records) == 6
    assert [r.stem for r in outcome.failed] == ["zz_corrupt"]
    report = json.loads((out / "report.json").read_text())
    assert report["sessions"] == 6 and report["calibrated"] == 5
    assert report["failed"][0]["file"].endswith("zz_corrupt.mcap")
    assert (
        "CRC" in report["failed"][0]["error"] or "corrupt" in report["failed"][0]["error"].lower()
    )
    groups = {(g["sensor_id"], g["mounting_id"]): g for g in report["groups"]}
    assert set(groups) == {("S1", "m1"), ("S1", "m2")}
    g = groups[("S1", "m1")]
    cals = [json.loads((out / f"r{i}.calibration.json").read_text()) for i in range(3)]
    for name in ("gain_x", "offset_z_mps2", "tilt_deg", "euler_2_deg"):
        values = np.array([c["parameters"][name]["value"] for c in cals])
        stds = np.array([c["parameters"][name]["std"] for c in cals])
        stats = g["parameters"][name]
        assert stats["mean"] == pytest.approx(values.mean(), rel=1e-12)
        assert stats["std"] == pytest.approx(values.std(ddof=1), rel=1e-12)
        assert stats["predicted_std"] == pytest.approx(math.sqrt(np.mean(stds**2)), rel=1e-12)
        assert stats["ratio"] == pytest.approx(values.std(ddof=1) / math.sqrt(np.mean(stds**2)))
    md = (out / "report.md").read_text()
    assert "zz_corrupt.mcap" in md and "| `gain_x` |" in md
    csv_rows = (out / "sessions.csv").read_text().strip().splitlines()
    # one row per session, the failed one included (its status says so)
    assert len(csv_rows) == 1 + 6 and csv_rows[0].startswith("file,sensor_id,mounting_id")
    assert not list(out.glob("*.tmp*")) and not (out / "zz_corrupt.calibration.json").exists()


def test_rerun_does_no_work_and_changed_input_reruns_one(tmp_path, recordings):
    inputs = tmp_path / "in"
    shutil.copytree(recordings, inputs)
    (inputs / "zz_corrupt.mcap").unlink()
    pipeline = _pipeline(tmp_path, inputs)
    first = run_batch(pipeline)
    assert not first.failed and first.report_written
    out = tmp_path / "out"
    mtimes = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    second = run_batch(pipeline)
    assert len(second.skipped) == 5 and not second.report_written
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == mtimes  # nothing rewritten
    # A changed recording is recalculated, and only that one.
    shutil.copy(recordings / "r4.mcap", inputs / "r1.mcap")
    third = run_batch(pipeline)
    assert [r.stem for r in third.records if not r.skipped] == ["r1"]
    assert third.report_written


def test_batch_cli_exit_status_and_progress_lines(tmp_path, recordings, capsys):
    pipeline = _pipeline(tmp_path, recordings)
    status = main(["batch", pipeline.path])
    captured = capsys.readouterr()
    assert status == 1
    assert "zz_corrupt.mcap" in captured.err and "FAILED" in captured.err
    # Plain log lines when not a terminal: one per session, counted 1/6 … 6/6, five `ok` lines
    # naming each good recording and one FAILED line; no progress bar.
    lines = [ln for ln in captured.err.splitlines() if re.match(r"\[\d+/\d+\] ", ln)]
    assert sorted(int(re.match(r"\[(\d+)/6\] ", ln).group(1)) for ln in lines) == [1, 2, 3, 4, 5, 6]
    ok = sorted(re.match(r"\[\d/6\] ok (\S+)", ln).group(1) for ln in lines if " ok " in ln)
    assert [Path(s).name for s in ok] == [f"r{i}.mcap" for i in range(5)], lines
    assert sum(" FAILED " in ln and "zz_corrupt.mcap" in ln for ln in lines) == 1, lines
    assert "\r" not in captured.err and "sessions, " not in captured.err
    # The summary and report.md say the same (a failed session is not "calibrated now").
    assert "6 sessions: 5 calibrated, 1 failed" in captured.out
    assert "6 sessions: 5 calibrated, 1 failed." in (tmp_path / "out" / "report.md").read_text()


def test_sessions_run_on_one_blas_thread_and_an_in_process_batch_gives_them_back(
    tmp_path, recordings, monkeypatch
):
    from threadpoolctl import threadpool_info, threadpool_limits

    from wheelcal.batch import runner

    def blas_threads():
        return {
            i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"
        }

    seen = []
    calibrate = runner.calibrate_session

    def spy(*args, **kwargs):
        seen.append(blas_threads())
        return calibrate(*args, **kwargs)

    monkeypatch.setattr(runner, "calibrate_session", spy)
    with threadpool_limits(2):
        before = blas_threads()
        outcome = run_batch(_pipeline(tmp_path, recordings, "workers = 1"))
        after = blas_threads()
    assert len(outcome.records) == 6 and len(seen) == 6
    assert set(before.values()) == {2} and after == before
    assert all(set(threads.values()) == {1} for threads in seen)


def test_dask_executor_on_a_local_cluster(tmp_path, recordings):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        pipeline = _pipeline(
            tmp_path, recordings, f'kind = "dask"\naddress = "{cluster.scheduler_address}"'
        )
        outcome = run_batch(pipeline)
    assert len(outcome.records) == 6 and len(outcome.failed) == 1
    (tmp_path / "local").mkdir()
    local = run_batch(_pipeline(tmp_path / "local", recordings))
    assert [r.stem for r in local.failed] == ["zz_corrupt"]
    # Same numbers whichever executor ran the session.
    a = json.loads((tmp_path / "out" / "r2.calibration.json").read_text())
    b = json.loads((tmp_path / "local" / "out" / "r2.calibration.json").read_text())
    assert a["parameters"]["gain_y"]["value"] == b["parameters"]["gain_y"]["value"]


def test_dask_runs_sessions_in_groups_and_a_failed_group_again_one_by_one(
    tmp_path, recordings, monkeypatch
):
    distributed = pytest.importorskip("distributed")
    from wheelcal.batch import runner

    log = tmp_path / "groups.txt"  # the function is pickled to the workers: a file, not a list
    run_group = runner._run_group

    def group_dies_with_r1(tasks):  # as a worker killed by session r1 takes its group along
        stems = sorted(t.stem for t in tasks)
        with open(log, "a") as stream:
            stream.write(" ".join(stems) + "\n")
        if "r1" in stems:
            raise RuntimeError("worker died")
        return run_group(tasks)

    monkeypatch.setattr(runner, "_run_group", group_dies_with_r1)
    monkeypatch.setattr(runner, "_GROUPS_PER_THREAD", 1)  # 6 sessions on 2 threads: 2 groups
    with distributed.LocalCluster(  # in-process workers: they see the patched function
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster:
        pipeline = _pipeline(
            tmp_path, recordings, f'kind = "dask"\naddress = "{cluster.scheduler_address}"'
        )
        outcome = run_batch(pipeline)
    groups = sorted(line.split() for line in log.read_text().splitlines())
    assert groups == [
        ["r0"],
        ["r0", "r1", "r2"],
        ["r1"],
        ["r2"],
        ["r3", "r4", "zz_corrupt"],
    ]
    assert sorted(r.stem for r in outcome.failed) == ["r1", "zz_corrupt"]
    (r1,) = [r for r in outcome.records if r.stem == "r1"]
    assert r1.error.endswith("worker failed: RuntimeError: worker died")
    assert (tmp_path / "out" / "r0.calibration.json").exists()
    assert json.loads((tmp_path / "out" / "report.json").read_text())["sessions"] == 6


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            "[pipeline]\nname='x'\n[inputs]\nglobs=['a/*.mcap']\n[run]\nrerun=true\ncalbrate=true\n",
            "calbrate",
        ),
        ("[pipeline]\nname='x'\n", "no inputs"),
        ("[pipelin]\nname='x'\n", "unknown section"),
        ("[inputs]\nglobs=['a']\n[executor]\nkind='dask'\n", "address"),
        ("[inputs\n", "not valid TOML"),
    ],
)
def test_pipeline_errors_name_the_file_and_the_key(tmp_path, body, message):
    path = tmp_path / "bad.toml"
    path.write_text(textwrap.dedent(body))
    with pytest.raises(PipelineError, match=message) as exc:
        load_pipeline(path)
    assert "bad.toml" in str(exc.value)


def test_globs_that_match_nothing_are_a_usage_error(tmp_path, capsys):
    path = tmp_path / "p.toml"
    path.write_text(
        f"[pipeline]\noutput='{tmp_path / 'o'}'\n[inputs]\nglobs=['{tmp_path}/none/*.mcap']\n"
    )
    assert main(["batch", str(path)]) == 2
    assert "match no files" in capsys.readouterr().err


def test_calibrate_false_only_simulates_the_inputs(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(
        f"[pipeline]\noutput='{tmp_path / 'out'}'\n"
        "[simulate]\ncount=2\nseed=1\npush_and_stop=false\n[run]\ncalibrate=false\n"
    )
    outcome = run_batch(load_pipeline(path))
    assert outcome.simulated == 2 and outcome.records == ()
    # (and the folder's lock file, .wheelcal.lock: issue 40)
    made = sorted(p.name for p in (tmp_path / "out").iterdir() if not p.name.startswith("."))
    assert made == ["recordings"]
    assert len(list((tmp_path / "out" / "recordings").glob("*.mcap"))) == 2
