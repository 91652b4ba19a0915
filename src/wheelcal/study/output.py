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

from wheelcal.io.atomic import atomic_write_bytes, atomic_write_text
from wheelcal.study.report import csv_tables, summary_markdown, to_json
from wheelcal.study.runner import StudyResult

JSON_NAME = "study.json"
SUMMARY_NAME = "summary.md"
RRD_NAME = "study.rrd"


def _csv_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    if rows:
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: "" if v is None else v for k, v in row.items()})
    return buf.getvalue()


def write_outputs(
    result: StudyResult,
    out_dir: str | Path,
    command: str | None = None,
    plots: bool = True,
    rrd: bool = True,
) -> list[Path]:
    """Write every output of the study into ``out_dir`` (created if missing); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []

    def text(name: str, content: str) -> None:
        atomic_write_text(out / name, content)
        written.append(out / name)

    text(JSON_NAME, json.dumps(to_json(result, command), indent=1, allow_nan=False) + "\n")
    for name, rows in csv_tables(result).items():
        text(name, _csv_text(rows))
    summary = summary_markdown(result, command)
    text(SUMMARY_NAME, summary)
    if plots:
        from wheelcal.study.plots import FIGURES

        for name, figure in FIGURES.items():
            atomic_write_bytes(out / name, figure(result))
            written.append(out / name)
    if rrd:
        from wheelcal.study.rerun_log import write_study_rrd

        written.append(write_study_rrd(out / RRD_NAME, result, summary))
    return written
