"""``wheelcal batch``: many sessions in parallel, one report.

1. Check that the output folder can be written (before any work), and generate
   the pipeline's simulated recordings, if it has a [simulate] section.
2. Plan: every input file gets a run key (:mod:`wheelcal.batch.provenance`);
   sessions whose calibration JSON (and .rrd, when asked for) carry the same key
   are up to date and skipped.
3. Run the rest on local processes (one BLAS thread each) or on a Dask cluster
   (a few sessions per Dask task: the scheduler's per-task work is shared).
   A failing session is recorded with its error, whatever the error (a
   MemoryError, a worker that dies); the batch goes on.  Each session runs
   under its lock (:mod:`wheelcal.batch.locking`), so two batches on one
   folder compute it once, and local workers die with the batch
   (:mod:`wheelcal.batch.workers`).
4. Pool each sensor's sessions into ``sensors/<sensor_id>.calibration.json``
   (:mod:`wheelcal.batch.sensors`), draw ``overview.png``, and write
   ``report.json``, ``report.md``, ``sessions.csv`` (and ``batch.rrd``)
   atomically — unless nothing changed since the last run.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import importlib
import json
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path

from threadpoolctl import ThreadpoolController

from wheelcal.batch.locking import FolderInUseError, pipeline_lock, report_lock, session_lock
from wheelcal.batch.pipeline import Pipeline, PipelineError
from wheelcal.batch.provenance import (
    file_sha256,
    read_document,
    run_key,
    run_key_of,
    stored_run_key,
)
from wheelcal.batch.session import calibrate_session, check_regular_file
from wheelcal.batch.stems import unique_stems
from wheelcal.batch.termination import (
    BatchStopped,
    Terminated,
    exit_worker,
    in_worker,
    terminate_on_signals,
    worker_signals,
)
from wheelcal.batch.workers import (
    SESSION_IMPORTS,
    exit_with_parent,
    start_fork_server,
    start_method,
    worker_context,
)
from wheelcal.calibration import Calibration, SessionOutcome, failed_outcome, session_outputs
from wheelcal.io import OutputFolderError, prepare_output_folder
from wheelcal.recording import RecordingError
from wheelcal.runtime import tune_allocator
from wheelcal.session import SessionOptions


@dataclass(frozen=True)
class ProgressEvent:
    """One step of progress: a session finished, or a message."""

    done: int
    total: int
    record: SessionOutcome | None = None
    message: str = ""


@dataclass(frozen=True)
class BatchOutcome:
    """Everything the batch did."""

    pipeline: Pipeline
    records: tuple[SessionOutcome, ...]
    report_paths: tuple[str, ...]
    report_written: bool
    simulated: int
    wall_s: float

    @property
    def failed(self) -> list[SessionOutcome]:
        """Sessions that failed."""
        return [r for r in self.records if not r.ok]

    @property
    def skipped(self) -> list[SessionOutcome]:
        """Sessions whose outputs were up to date."""
        return [r for r in self.records if r.skipped]

    def counts(self) -> dict:
        """Session counts with the keys of ``report.json`` (so both say the same)."""
        return {
            "sessions": len(self.records),
            "calibrated": sum(r.ok for r in self.records),
            "skipped_up_to_date": len(self.skipped),
            "failed": [r.source for r in self.failed],
        }


@dataclass(frozen=True)
class _Task:
    path: str
    options: SessionOptions
    out_dir: str
    key: str
    input_sha256: str
    stem: str


def _run_task(task: _Task) -> SessionOutcome:
    """Worker entry point (top level: it must pickle).

    The session's lock is held while it runs; once it has the lock, a session
    that another batch on the same folder has just written is skipped.
    """
    tune_allocator()
    try:
        with session_lock(task.out_dir, task.stem):
            if _up_to_date(Path(task.out_dir), task.stem, task.key, task.options):
                return _up_to_date_record(
                    task.path, Path(task.out_dir), task.stem, task.options.rrd
                )
            with _blas_threads().limit(limits=1):
                outcome = calibrate_session(
                    task.path,
                    task.options,
                    task.out_dir,
                    provenance={"run_key": task.key, "input_sha256": task.input_sha256},
                    durable=False,  # atomic, not fsync-ed one by one: run_batch syncs once
                    stem=task.stem,
                )
    except Terminated as exc:
        if in_worker():  # told to stop by the batch: its temporary files are already gone
            exit_worker(exc)
        raise
    # small: the calibrated session stays in the worker
    return dataclasses.replace(outcome, session=None)


@functools.cache
def _blas_threads() -> ThreadpoolController:
    """The BLAS libraries of this process, found once (a search costs ~1.5 ms a session).

    Found at the first session, when the estimation stack (numpy's and scipy's
    BLAS) is loaded; a library loaded later would only keep its own thread
    count.  ``limit`` is a context: a batch run in-process (one worker) gives
    the caller's process its threads back.
    """
    return ThreadpoolController()


def _calibration_file(out: Path, stem: str) -> Path:
    """A session's calibration JSON, which marks it complete (written last)."""
    return out / f"{stem}.calibration.json"


def _up_to_date(out: Path, stem: str, key: str, options: SessionOptions) -> bool:
    """The session's outputs exist and carry this run key."""
    rrd = out / f"{stem}.rrd"
    diag = out / f"{stem}.diagnosis.json"
    complete = (not options.rrd or rrd.exists()) and (not options.diagnose or diag.exists())
    return complete and stored_run_key(_calibration_file(out, stem)) == key


def _up_to_date_record(source: str, out: Path, stem: str, rrd: bool) -> SessionOutcome:
    return SessionOutcome(
        source=source,
        stem=stem,
        calibration_path=str(_calibration_file(out, stem)),
        rrd_path=str(out / f"{stem}.rrd") if rrd else None,
        skipped=True,
    )


#: Threads that hash the inputs while planning.
_HASH_THREADS = 4


def _fingerprint(path: Path) -> str | OSError | RecordingError:
    """The SHA-256 of an input file, or the error that stopped it."""
    try:
        check_regular_file(path)  # before hashing: a FIFO would block, /dev/zero never end
        return file_sha256(path)
    except (OSError, RecordingError) as exc:
        return exc


def _import_for_workers(in_process: bool) -> None:
    """Import what a session imports on first use (``scipy.signal``: ≈ 0.6 s) here, once.

    For sessions run in this process, and for workers forked from it (``fork``:
    they inherit its modules; without this each would import them on its first
    session).  Under ``forkserver`` the fork server preloads them instead
    (:mod:`wheelcal.batch.workers`): this process, which only plans and reports,
    starts the server here, so its imports run beside the hashing.  ``spawn``-ed
    workers import them themselves.  (Not Rerun:
    it starts threads when imported, and a process should not fork with threads it
    does not control.)
    """
    if not in_process and start_method() != "fork":
        start_fork_server()  # its imports beside the hashing, not after it
        return
    for name in SESSION_IMPORTS:
        importlib.import_module(name)


def _in_process(pipeline: Pipeline, sessions: int) -> bool:
    """Whether a local batch of ``sessions`` runs them in this process (one worker)."""
    return min(pipeline.executor.workers or os.cpu_count() or 1, sessions) == 1


def _new_sessions(out: Path, stems) -> int:
    """How many sessions have no calibration yet: those will certainly run.

    (A re-run with every session up to date forks no worker and skips the imports;
    one that adds a single recording runs it in this process.)
    """
    return sum(not _calibration_file(out, stem).exists() for stem in stems)


def _plan(pipeline: Pipeline, files: list[Path]) -> tuple[list[_Task], list[SessionOutcome]]:
    try:
        stems = unique_stems(files)
    except ValueError as exc:
        raise PipelineError(f"{pipeline.path}: {exc}") from None
    out = pipeline.output
    produces = {"rrd": pipeline.rerun}
    tasks, up_to_date = [], []
    # hashlib and file reads release the GIL: a few threads hash several inputs at once,
    # while this thread imports what each forked worker would otherwise import itself
    with ThreadPoolExecutor(min(_HASH_THREADS, len(files) or 1)) as pool:
        pending = pool.map(_fingerprint, files)
        new = _new_sessions(out, stems.values()) if pipeline.executor.kind == "processes" else 0
        if new:
            _import_for_workers(_in_process(pipeline, new))
        fingerprints = list(pending)
    for f, sha in zip(files, fingerprints, strict=True):
        stem = stems[str(f)]
        if not isinstance(sha, str):
            # An input that became unreadable: its earlier outputs must not pass for this run's.
            error = (
                str(sha)
                if isinstance(sha, RecordingError)
                else f"cannot read ({sha.strerror or sha})"
            )
            up_to_date.append(failed_outcome(str(f), stem, out, error))
            continue
        options = pipeline.options_for(f)
        key = run_key(sha, options, produces)
        if _up_to_date(out, stem, key, options):
            up_to_date.append(_up_to_date_record(str(f), out, stem, pipeline.rerun))
        else:
            tasks.append(_Task(str(f), options, str(out), key, sha, stem))
    return tasks, up_to_date


def _execute(
    pipeline: Pipeline,
    tasks: list[_Task],
    on_done: Callable[[SessionOutcome], None],
    stop: Callable[[], bool] = lambda: False,
) -> None:
    """Run the tasks, reporting each record; no new session starts once ``stop()`` is true."""
    executor = pipeline.executor
    if not tasks:
        return
    if executor.kind == "dask":
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed

        try:
            client = Client(executor.address, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise PipelineError(
                f"{pipeline.path}: [executor] cannot reach the Dask scheduler at "
                f"{executor.address}: {exc}"
            ) from None
        with client:
            size = _group_size(len(tasks), sum(client.nthreads().values()))
            groups = [tuple(tasks[i : i + size]) for i in range(0, len(tasks), size)]
            pending = {client.submit(_run_group, group, pure=False): group for group in groups}
            finished = dask_completed(pending)
            for future in finished:
                group = pending.pop(future)
                try:
                    records = future.result()
                except Exception as exc:  # the group as a whole: its worker died, or worse
                    if len(group) == 1:
                        records = [_failed_record(group[0], exc)]
                    else:  # again one by one, so that only the session at fault fails
                        for task in group:
                            single = client.submit(_run_group, (task,), pure=False)
                            pending[single] = (task,)
                            finished.add(single)
                        continue
                for record in records:
                    on_done(record)
        return
    workers = executor.workers or os.cpu_count() or 1
    workers = min(workers, len(tasks))
    if workers == 1:
        for task in tasks:
            if stop():
                return
            try:
                record = _run_task(task)
            except Exception as exc:  # one session must never stop the batch
                record = _failed_record(task, exc)
            on_done(record)
        return
    broken = _run_pool(tasks, workers, on_done, stop)
    # A worker that died (killed by the OOM killer, a segfault) breaks the whole pool: every
    # session still pending fails with it.  Re-run those on a fresh pool while that makes
    # progress, then one per fresh worker, so only the session that kills its worker fails.
    while broken and len(broken) > 1 and not stop():
        retry = _run_pool(broken, workers, on_done, stop)
        if len(retry) == len(broken):  # no session finished: isolate them
            break
        broken = retry
    for task in broken:
        if stop():
            return
        for lost in _run_pool([task], 1, on_done, stop):
            on_done(_failed_record(lost, BrokenProcessPool()))


#: Most sessions in one Dask task, and fewest tasks per worker thread (load balance).
_GROUP_MAX, _GROUPS_PER_THREAD = 8, 16


def _group_size(sessions: int, threads: int) -> int:
    """Sessions per Dask task: several, so the scheduler's per-task work is shared.

    The scheduler and client usually run beside the workers (~1–2 ms of CPU
    per task); a group of up to 8 sessions (~0.5 s) still leaves 16 tasks per
    worker thread for balance, and progress is reported group by group.
    """
    return max(1, min(_GROUP_MAX, sessions // max(1, _GROUPS_PER_THREAD * threads)))


def _run_group(tasks: tuple[_Task, ...]) -> list[SessionOutcome]:
    """Several sessions in one task (top level: it must pickle); each fails alone."""
    records = []
    for task in tasks:
        try:
            records.append(_run_task(task))
        except Exception as exc:  # one session must never stop the others
            records.append(_failed_record(task, exc))
    return records


def _run_pool(
    tasks: list[_Task],
    workers: int,
    on_done: Callable[[SessionOutcome], None],
    stop: Callable[[], bool] = lambda: False,
) -> list[_Task]:
    """Run tasks on a process pool; returns the tasks lost to a broken pool (not reported).

    Once ``stop()`` is true the sessions not started are cancelled (those running
    finish).  On an interruption (a signal, ``Ctrl-C``) the workers are stopped
    at once, each removing its temporary files (:func:`_stop_workers`).
    """
    broken = []
    pool = ProcessPoolExecutor(
        workers,
        mp_context=worker_context(),
        initializer=_worker_start,
        initargs=(os.getpid(),),
    )
    try:
        futures = {}
        for i, task in enumerate(tasks):
            try:
                futures[pool.submit(_run_task, task)] = task
            except BrokenProcessPool:
                broken.extend(tasks[i:])
                break
        for future in as_completed(futures):
            if future.cancelled():
                continue
            if isinstance(future.exception(), BrokenProcessPool):
                broken.append(futures[future])
            else:
                on_done(_collect(future, futures[future]))
            if stop():
                for pending in futures:
                    pending.cancel()
    except BaseException:
        _stop_workers(pool)
        raise
    pool.shutdown(wait=True)
    return sorted(broken, key=lambda t: t.path)


def _worker_start(batch_pid: int) -> None:
    """Pool initializer: die with the batch, and stop cleanly when it says so."""
    exit_with_parent(batch_pid)
    worker_signals()


#: How long stopped workers get to remove their temporary files, s.
_STOP_WAIT_S = 20.0


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started; send the workers SIGTERM; wait for them (then kill)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        with contextlib.suppress(OSError, ValueError, AttributeError):
            process.terminate()  # SIGTERM: its writers remove their temporary files
    deadline = time.monotonic() + _STOP_WAIT_S
    for process in processes:
        with contextlib.suppress(OSError, ValueError, AssertionError, AttributeError):
            process.join(max(0.0, deadline - time.monotonic()))
            if process.is_alive():
                process.kill()


def _collect(future, task: _Task) -> SessionOutcome:
    """The record of a finished future; a crashed worker becomes a failed session."""
    try:
        return future.result()
    except Exception as exc:  # one session must never stop the batch
        return _failed_record(task, exc)


def _failed_record(task: _Task, exc: BaseException) -> SessionOutcome:
    """A session whose worker raised or died: named, and its earlier outputs marked stale."""
    if isinstance(exc, BrokenProcessPool):
        what = "its worker process died (out of memory, or killed)"
    else:
        what = f"worker failed: {type(exc).__name__}: {exc}"
    return failed_outcome(task.path, task.stem, task.out_dir, what)


def run_batch(
    pipeline: Pipeline,
    progress: Callable[[ProgressEvent], None] | None = None,
    force: bool = False,
) -> BatchOutcome:
    """Run a pipeline end to end (see the module docstring).

    ``force``: replace outputs wheelcal did not write from these inputs too
    (the overwrite policy, :mod:`wheelcal.io.ownership`).

    Raises
    ------
    PipelineError
        Before any work: the folder cannot be written, is used by another batch
        with a different pipeline, or holds outputs the policy does not replace.
    BatchStopped
        The disk filled up: the sessions written are complete and kept, the
        report was not written (an earlier one is unchanged).
    Terminated
        A SIGTERM or SIGHUP (with ``done``/``total``): the sessions finished are
        complete, the others left no file.
    """
    t0 = time.perf_counter()
    say = progress or (lambda event: None)
    if pipeline.executor.kind == "dask":
        _require_dask(pipeline)
    try:
        prepare_output_folder(pipeline.output)  # before any work: a read-only folder wastes it
    except OutputFolderError as exc:
        raise PipelineError(f"{pipeline.path}: {exc}") from None
    with contextlib.ExitStack() as stack:
        who = f"pipeline {pipeline.name!r}, {pipeline.path}"
        try:
            alone = stack.enter_context(pipeline_lock(pipeline.output, _identity(pipeline), who))
        except FolderInUseError as exc:
            raise PipelineError(f"{pipeline.path}: {exc}") from None
        if alone:  # no other batch writes here: what temporaries there are, a killed run left
            removed = _remove_temporaries(pipeline.output)
            if removed:
                say(
                    ProgressEvent(
                        0,
                        0,
                        message=f"removed {removed} temporary file(s) an interrupted run left",
                    )
                )
        return _run_held(pipeline, say, force, t0)


def _run_held(pipeline: Pipeline, say, force: bool, t0: float) -> BatchOutcome:
    """:func:`run_batch` once the output folder is held for this pipeline."""
    from wheelcal.batch.simulate_inputs import simulate_inputs

    made = simulate_inputs(pipeline, lambda msg: say(ProgressEvent(0, 0, message=msg)))
    if not pipeline.calibrate:  # [run] calibrate = false: only make the simulated inputs
        return BatchOutcome(pipeline, (), (), False, len(made), time.perf_counter() - t0)
    files = pipeline.input_files()
    if not files:
        raise PipelineError(
            f"{pipeline.path}: the input globs match no files: {list(pipeline.globs)}"
        )
    tasks, records = _plan(pipeline, files)
    notes = _claim(pipeline, tasks, force)  # before any session: a refusal costs nothing
    if notes:
        say(ProgressEvent(0, 0, message=_replacing(notes)))
    total = len(files)
    if records:
        fresh = sum(r.skipped for r in records)
        say(
            ProgressEvent(
                len(records), total, message=f"{fresh} session(s) up to date, {len(tasks)} to run"
            )
        )
    full: list[SessionOutcome] = []

    def done(record: SessionOutcome) -> None:
        records.append(record)
        if record.disk_full:
            full.append(record)
        say(ProgressEvent(len(records), total, record=record))

    try:
        with terminate_on_signals():
            _execute(pipeline, tasks, done, stop=lambda: bool(full))
            _sync()  # the sessions' files, durable in one flush (they skipped per-file fsync)
            if full:
                raise BatchStopped(_disk_full_text(pipeline, records, total, full[0]))
            records.sort(key=lambda r: r.source)
            with report_lock(pipeline.output):  # another batch on this folder may be writing it
                paths, written = _write_report(pipeline, records)
    except Terminated as exc:
        exc.done, exc.total = sum(r.ok and not r.skipped for r in records), len(tasks)
        raise
    return BatchOutcome(
        pipeline=pipeline,
        records=tuple(records),
        report_paths=paths,
        report_written=written,
        simulated=len(made),
        wall_s=time.perf_counter() - t0,
    )


def _identity(pipeline: Pipeline) -> str:
    """What a pipeline computes, hashed: two runs of it may share a folder, two pipelines not.

    The inputs (globs made absolute), the simulated inputs, the session options and
    what is run; not the executor (workers) nor the output folder.
    """
    payload = {
        "name": pipeline.name,
        "globs": [os.path.abspath(g) for g in pipeline.globs],
        "simulate": pipeline.simulate,
        "options": dataclasses.asdict(pipeline.options),
        "run": [pipeline.calibrate, pipeline.diagnose, pipeline.closure, pipeline.rerun],
    }
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()


def _remove_temporaries(out: Path) -> int:
    """Remove the hidden temporary files a killed batch left in ``out`` and ``out/sensors``."""
    from wheelcal.batch.sensors import SENSORS_FOLDER
    from wheelcal.io import remove_temporaries

    return len(remove_temporaries(out)) + len(remove_temporaries(out / SENSORS_FOLDER))


#: The report set: the files of :func:`_write_report` (sensor files: those that exist).
_REPORT_FILES = ("report.json", "report.md", "sessions.csv", "overview.png", "batch.rrd")


def _claim(pipeline: Pipeline, tasks: list[_Task], force: bool) -> list[str]:
    """The overwrite policy on every file the batch may write (PipelineError if refused)."""
    from wheelcal.batch.sensors import SENSORS_FOLDER
    from wheelcal.io import Output, OutputRefusedError, claim_outputs, origin_of

    out, options = pipeline.output, pipeline.options
    sessions = [
        o
        for t in tasks
        for o in session_outputs(t.path, out, options.rrd, options.diagnose, t.stem)
    ]
    origin, inputs = origin_of([pipeline.path]), (pipeline.path,)
    sensors = sorted((out / SENSORS_FOLDER).glob("*.calibration.json")) + sorted(
        (out / SENSORS_FOLDER).glob("*.sensor.json")
    )
    report = [
        Output(p, origin, inputs, follows=p.suffix == ".csv")
        for p in [out / name for name in _REPORT_FILES] + sensors
    ]
    try:
        return claim_outputs(sessions, force) + claim_outputs(report, force)
    except OutputRefusedError as exc:
        raise PipelineError(f"{pipeline.path}: {exc}") from None


def _replacing(notes: list[str]) -> str:
    """One progress line for the earlier outputs the batch replaces."""
    if len(notes) == 1:
        return notes[0]
    return f"{notes[0]}; and {len(notes) - 1} more earlier output(s) of the same inputs"


def _disk_full_text(pipeline, records, total: int, first: SessionOutcome) -> str:
    written = sum(r.ok and not r.skipped for r in records)
    skipped = sum(r.skipped for r in records)
    reason = first.error.removeprefix(f"{first.source}: ")
    return (
        f"the disk of {pipeline.output} is full: the batch stopped at {first.source} "
        f"({reason}). {written} session(s) were calibrated and written before it filled "
        f"(complete, kept), {skipped} were up to date, {total - written - skipped} are not "
        "written; the report was not written (an earlier one is unchanged). Free some space "
        "and run the batch again: only the sessions without outputs are redone"
    )


def _require_dask(pipeline: Pipeline) -> None:
    """Refuse a Dask pipeline before any work when the ``dask`` extra is missing."""
    try:
        import dask.distributed  # noqa: F401
    except ImportError as exc:
        raise PipelineError(
            f'{pipeline.path}: [executor] kind = "dask" needs the dask extra, which is not '
            f"installed ({exc}): pip install 'wheelcal[dask]' (or \"dask[distributed]\"), on "
            "this machine and on every worker"
        ) from None


def _write_report(
    pipeline: Pipeline, records: list[SessionOutcome]
) -> tuple[tuple[str, ...], bool]:
    """The report set, all at once or not at all (staged: a full disk leaves the earlier set)."""
    from wheelcal.io import origin_of, output_mark, staged_outputs

    out = pipeline.output
    json_path = out / "report.json"
    # each calibration JSON read once: its run key now, its Calibration below
    documents = {
        r.calibration_path: read_document(Path(r.calibration_path)) for r in records if r.ok
    }
    report_key = _report_key(records, documents)
    stored_key, stored_outputs = _stored_report(json_path)
    if (
        stored_key == report_key
        and stored_outputs
        and all(Path(p).exists() for p in stored_outputs)
    ):
        return tuple(stored_outputs), False
    calibrations = [
        _calibration(r.calibration_path, documents.pop(r.calibration_path)) for r in records if r.ok
    ]
    origin = origin_of([pipeline.path])
    mark = output_mark(origin, [pipeline.path])
    try:
        # report.json last: its key marks the whole report as complete.
        with staged_outputs(durable=False, last=(json_path,)) as stage:
            paths = _stage_report(pipeline, records, calibrations, report_key, stage, mark)
            _sync()  # every staged file durable, in one flush, before any is installed
    except OSError as exc:
        from wheelcal.io import describe_error, disk_full

        if not disk_full(exc, out):
            raise
        raise BatchStopped(
            f"{out}: the disk is full ({describe_error(exc)}): every session is written, but "
            "the report was not (an earlier one is unchanged). Free some space and run the "
            "batch again: only the report is made"
        ) from None
    return tuple(map(str, paths)), True


def _stage_report(pipeline, records, calibrations, report_key: str, stage, mark) -> list[Path]:
    """Stage every file of the report set (:func:`_write_report`); their paths."""
    from wheelcal.batch.report import report_markdown, sessions_csv
    from wheelcal.io import MARK_KEY, dumps_indented, json_safe, mark_line

    out = pipeline.output
    json_path, md_path, csv_path = out / "report.json", out / "report.md", out / "sessions.csv"
    report = _report(pipeline, records, calibrations, stage, mark)
    numbers = [i + 1 for i, r in enumerate(records) if r.ok]  # as report.md's session table
    paths = [
        json_path,
        md_path,
        csv_path,
        *_sensor_and_overview_files(pipeline, records, calibrations, report, numbers, stage, mark),
    ]
    batch_rrd = pipeline.rerun and bool(calibrations)  # nothing to draw when every session failed
    if batch_rrd:
        paths.append(out / "batch.rrd")
    elif pipeline.rerun and (out / "batch.rrd").exists():
        stage.move(out / "batch.rrd", out / "batch.stale.rrd")  # not this run's
    report["pipeline"] = {"name": pipeline.name, "file": pipeline.path}
    report["provenance"] = {"report_key": report_key, "outputs": [str(p) for p in paths]}
    report[MARK_KEY] = mark
    markdown = report_markdown(report, f"Repeatability report — {pipeline.name}")
    stage.write_text(md_path, markdown + f"\n<!-- {mark_line(mark['origin'])} -->\n")
    stage.write_text(csv_path, sessions_csv(calibrations, report["per_session"]))
    if batch_rrd:
        from wheelcal.viz import write_batch_rrd

        with stage.path(out / "batch.rrd") as tmp:
            write_batch_rrd(tmp, calibrations, numbers, report, durable=False, name="batch")
    stage.write_text(json_path, dumps_indented(json_safe(report)) + "\n")
    return paths


def _report_key(records: list[SessionOutcome], documents: dict[str, dict | None]) -> str:
    """What the report is made of: every session's run key (or its error), hashed."""
    keys = sorted(
        (r.source, r.stem, run_key_of(documents[r.calibration_path]) if r.ok else r.error)
        for r in records
    )
    return hashlib.sha256(json.dumps(keys).encode()).hexdigest()


def _report(
    pipeline: Pipeline,
    records: list[SessionOutcome],
    calibrations: list[Calibration],
    stage=None,
    mark: dict | None = None,
) -> dict:
    """``report.json``'s statistics, sessions and (with the closed loop) its closure."""
    from wheelcal.batch.report import build_report

    diagnoses = []
    if pipeline.diagnose:
        for r in records:
            if r.ok:
                path = Path(r.calibration_path).with_name(f"{r.stem}.diagnosis.json")
                diagnoses.append(json.loads(path.read_text(encoding="utf-8")))
    failed = [_failure(r) for r in records if not r.ok]
    per_session = [
        {**_failure(r), "stem": r.stem, "status": r.status, "calibration": r.calibration_path}
        for r in records
    ]
    report = build_report(
        calibrations,
        failed,
        skipped=sum(r.skipped for r in records),
        diagnoses=diagnoses,
        per_session=per_session,
    )
    if pipeline.closure:
        from wheelcal.batch.closure import run_closure

        report["closure"] = run_closure(pipeline, calibrations, stage=stage, mark=mark)
    return report


def _sensor_and_overview_files(
    pipeline: Pipeline,
    records: list[SessionOutcome],
    calibrations: list[Calibration],
    report: dict,
    numbers: list[int],
    stage,
    mark: dict,
) -> list[Path]:
    """Stage each sensor's pooled calibration and ``overview.png``; note them in ``report``."""
    from wheelcal.batch.sensors import write_sensor_calibrations
    from wheelcal.viz import OVERVIEW_FILE, overview_png

    out = pipeline.output
    sensors = write_sensor_calibrations(
        out,
        calibrations,
        {r.source: r.calibration_path for r in records if r.ok},
        report.get("closure"),
        stage=stage,
        mark=mark,
    )
    report["sensors"] = [s.summary() for s in sensors]
    paths = [s.path for s in sensors]
    png, note = overview_png(
        calibrations,
        [s.doc for s in sensors],
        title=pipeline.name,
        numbers=numbers,
        origin=mark["origin"],
    )
    if png is not None:
        stage.write_bytes(out / OVERVIEW_FILE, png)
        paths.append(out / OVERVIEW_FILE)
        report["overview"] = {"file": OVERVIEW_FILE}
    else:
        report["overview"] = {"file": None, "note": note}
    return paths


def _calibration(path: str, document: dict | None) -> Calibration:
    """The Calibration of a document read from ``path``; unreadable: read again, to say why."""
    if document is None:
        return Calibration.from_json(path)
    return Calibration.from_document(document, path)


def _failure(record: SessionOutcome) -> dict:
    """A ``report.json`` ``failed`` entry: file and error, plus gate and fix when refused."""
    entry = {"file": record.source, "error": record.error}
    if record.gate:
        entry["gate"] = record.gate
        entry["fix"] = record.fix or ""
    return entry


def _sync() -> None:
    """Flush written files to disk (one sync instead of two fsyncs per file)."""
    if hasattr(os, "sync"):
        os.sync()


def _stored_report(path: Path) -> tuple[str | None, list[str]]:
    """The report key and the output list of an earlier ``report.json`` (None, [] if none)."""
    document = read_document(path)  # bounded, and never a FIFO put in its place
    try:
        provenance = (document or {}).get("provenance", {})
        return provenance.get("report_key"), list(provenance.get("outputs", []))
    except (AttributeError, TypeError):
        return None, []
