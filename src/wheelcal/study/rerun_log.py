"""The study as a Rerun recording (``study.rrd``; rerun-sdk 0.41, imported here only).

Written through :func:`wheelcal.viz.rrd_writer.rrd_file` (private stream, strict
mode, atomic write).  Curves are scalar series sent column-wise
(``send_columns``), indexed by sequence timelines in integer units:

* ``sigma_n_umps2`` (σ_n in µm/s²) — ``noise_sweep/<group>/<estimator>/<quantity>``
  for ``normalised_std`` (Fig. 8), ``normalised_deviation_pct`` (Fig. 7) and
  ``std_over_crlb``, the bound as ``noise_sweep/<group>/crlb/normalised_std``,
  and every parameter's ``parameters/<estimator>/<name>/{std,bias}``;
* ``duration_ms`` — ``duration/<offset|gain>/<wheel_crlb|static>``;
* ``rate_mhz`` (mHz) — ``rate/<offset|gain>/<wheel_crlb|static>``;

plus the Markdown summary at ``summary`` (static) and a blueprint with one
plot per group.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from wheelcal.study.duration import SENSOR_NAMES
from wheelcal.study.montecarlo import PARAMETER_GROUPS, group_of
from wheelcal.study.runner import StudyResult

APPLICATION_ID = "wheelcal_study"
SIGMA_TIMELINE = "sigma_n_umps2"


def _send(stream, rr, path: str, timeline: str, index: np.ndarray, values: np.ndarray) -> None:
    ok = np.isfinite(values)
    if not np.any(ok):
        return
    stream.send_columns(
        path,
        indexes=[rr.TimeColumn(timeline, sequence=index[ok].astype(np.int64))],
        columns=rr.Scalars.columns(scalars=values[ok].astype(np.float64)),
    )


def _blueprint(rrb):
    sweep = [
        rrb.TimeSeriesView(origin=f"/noise_sweep/{g}", name=f"{g}: σ, deviation, CRLB")
        for g in PARAMETER_GROUPS
    ]
    budget = [
        rrb.TimeSeriesView(origin=f"/{axis}/{g}", name=f"{g} σ vs {axis}")
        for axis in ("duration", "rate")
        for g in ("offset", "gain")
    ]
    return rrb.Blueprint(
        rrb.Tabs(
            rrb.TextDocumentView(origin="/summary", name="summary"),
            rrb.Grid(*sweep, grid_columns=3, name="noise sweep (Fig. 7-8)"),
            rrb.Grid(*budget, grid_columns=2, name="duration and rate"),
            active_tab=1,
        ),
        rrb.TimePanel(timeline=SIGMA_TIMELINE),
    )


def write_study_rrd(path: str | os.PathLike, result: StudyResult, summary_markdown: str) -> Path:
    """Write ``study.rrd`` (module docstring) atomically; returns ``path``."""
    import rerun as rr
    import rerun.blueprint as rrb

    from wheelcal.viz import rrd_file

    with rrd_file(path, APPLICATION_ID, f"wheelcal study (seed {result.config.seed})") as stream:
        stream.send_blueprint(_blueprint(rrb))
        stream.log(
            "summary", rr.TextDocument(summary_markdown, media_type="text/markdown"), static=True
        )
        for estimator, levels in result.sweep.items():
            sigma = np.array([round(s.sigma_mps2 * 1e6) for s in levels])
            for group in PARAMETER_GROUPS:
                for quantity in ("normalised_std", "normalised_deviation_pct", "std_over_crlb"):
                    vals = np.array([s.group_mean(getattr(s, quantity))[group] for s in levels])
                    _send(
                        stream, rr, f"noise_sweep/{group}/{estimator}/{quantity}",
                        SIGMA_TIMELINE, sigma, vals,
                    )  # fmt: skip
                if estimator == "joint":
                    vals = np.array([s.group_mean(s.crlb_normalised_std)[group] for s in levels])
                    _send(
                        stream, rr, f"noise_sweep/{group}/crlb/normalised_std",
                        SIGMA_TIMELINE, sigma, vals,
                    )  # fmt: skip
            for i, name in enumerate(levels[0].names):
                for quantity in ("std", "bias"):
                    vals = np.array([getattr(s, quantity)[i] for s in levels])
                    _send(
                        stream, rr, f"parameters/{estimator}/{name}/{quantity}",
                        SIGMA_TIMELINE, sigma, vals,
                    )  # fmt: skip
        for sweep, points, axis, timeline in (
            ("duration", result.durations, "duration_s", "duration_ms"),
            ("rate", result.rates, "rate_hz", "rate_mhz"),
        ):
            index = np.array([round(getattr(p, axis) * 1e3) for p in points])
            for group in ("offset", "gain"):
                idx = [i for i, n in enumerate(SENSOR_NAMES) if group_of(n) == group]
                for method, attr in (("wheel_crlb", "wheel_std"), ("static", "static_std")):
                    vals = np.array([np.mean(getattr(p, attr)[idx]) for p in points])
                    _send(stream, rr, f"{sweep}/{group}/{method}", timeline, index, vals)
    return Path(path)
