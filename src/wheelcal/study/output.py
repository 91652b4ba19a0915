"""Write a :class:`~wheelcal.study.runner.StudyResult` to a directory, every file atomically.

Files: ``study.json`` (everything), the CSV tables of
:func:`wheelcal.study.report.csv_tables`, ``summary.md``, the PNG figures of
:data:`wheelcal.study.plots.FIGURES` and ``study.rrd`` (Rerun).
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from wheelcal.io import MARK_KEY, atomic_write_bytes, atomic_write_text, mark_line
from wheelcal.study.report import csv_tables, summary_markdown, to_json
from wheelcal.study.runner import StudyResult

JSON_NAME = "study.json"
SUMMARY_NAME = "summary.md"
RRD_NAME = "study.rrd"
#: The CSV tables of :func:`wheelcal.study.report.csv_tables` (for the overwrite policy).
CSV_NAMES = (
    "noise_sweep.csv",
    "groups.csv",
    "ratios.csv",
    "table1.csv",
    "static.csv",
    "duration.csv",
    "checks.csv",
    "runs.csv",
)


def _csv_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    if rows:
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: "" if v is None else v for k, v in row.items()})
    return buf.getvalue()


def study_outputs(
    out_dir: str | Path, origin: str, inputs: tuple[str, ...], plots: bool, rrd: bool
):
    """The files :func:`write_outputs` writes, for the overwrite policy (claimed before the run).

    The CSV tables and figures carry no mark: they follow ``study.json``.
    """
    from wheelcal.io import Output
    from wheelcal.study.plots import FIGURES

    out = Path(out_dir)
    names = [JSON_NAME, SUMMARY_NAME] + ([RRD_NAME] if rrd else [])
    following = list(CSV_NAMES) + (list(FIGURES) if plots else [])
    return [Output(out / n, origin, inputs) for n in names] + [
        Output(out / n, origin, inputs, follows=True) for n in following
    ]


def write_outputs(
    result: StudyResult,
    out_dir: str | Path,
    command: str | None = None,
    plots: bool = True,
    rrd: bool = True,
    mark: dict | None = None,
) -> list[Path]:
    """Write every output of the study into ``out_dir`` (created if missing); returns the paths.

    ``mark``: the outputs' ``wheelcal.output`` mark (:mod:`wheelcal.io.ownership`),
    stored in ``study.json`` and ``summary.md``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []

    def text(name: str, content: str) -> None:
        atomic_write_text(out / name, content)
        written.append(out / name)

    document = to_json(result, command)
    if mark is not None:
        document[MARK_KEY] = mark
    text(JSON_NAME, json.dumps(document, indent=1, allow_nan=False) + "\n")
    for name, rows in csv_tables(result).items():
        text(name, _csv_text(rows))
    summary = summary_markdown(result, command)
    marked = f"\n<!-- {mark_line(mark['origin'])} -->\n" if mark is not None else ""
    text(SUMMARY_NAME, summary + marked)
    if plots:
        from wheelcal.study.plots import FIGURES

        for name, figure in FIGURES.items():
            atomic_write_bytes(out / name, figure(result))
            written.append(out / name)
    if rrd:
        from wheelcal.study.rerun_log import write_study_rrd

        written.append(write_study_rrd(out / RRD_NAME, result, summary))
    return written
