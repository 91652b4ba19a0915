"""``wheelcal study`` — the synthetic accuracy study of the paper's Sec. IV-A (Table I, Fig. 7–8).

Settings come from ``--config`` (a TOML file, e.g. ``pipelines/table1-study.toml``)
or the defaults of :class:`wheelcal.study.config.StudyConfig`; the options below
override either.  ``--quick`` is the reduced study the test suite runs (about
half a minute on two cores).  Outputs go to ``--out``: ``study.json``, CSV
tables, ``summary.md``, PNG figures and ``study.rrd``.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time

from wheelcal.cli.errors import UsageError
from wheelcal.cli.overwrite import FORCE_HELP, POLICY_EPILOG

#: Overrides of ``--quick``: the Table I levels only, few runs, a short duration sweep.
QUICK = {
    "noise_sweep.levels": 0,
    "noise_sweep.realisations": 24,
    "noise_sweep.paper_realisations": 8,
    "static.realisations": 400,
    "duration.durations_s": (30.0, 90.0),
    "duration.rates_hz": (100.0, 200.0),
    "duration.check_durations_s": (30.0,),
    "duration.check_rates_hz": (),
    "duration.check_realisations": 12,
}

#: Option → dotted config field.
_OVERRIDES = {
    "levels": "noise_sweep.levels",
    "sigma_min": "noise_sweep.sigma_min_mps2",
    "sigma_max": "noise_sweep.sigma_max_mps2",
    "realisations": "noise_sweep.realisations",
    "paper_realisations": "noise_sweep.paper_realisations",
    "static_realisations": "static.realisations",
    "settle_s": "static.settle_s",
    "check_realisations": "duration.check_realisations",
    "workers": "workers",
    "seed": "seed",
}


def _plain(text: str) -> str:
    """Docstring text for a terminal: ``literal`` and :role:`~a.b.c` markup as plain words."""
    import re

    text = re.sub(r":[a-z]+:`~?(?:[\w.]+\.)?([\w]+)`", r"\1", text)
    return text.replace("``", "")


def register(subparsers) -> None:
    """Add the ``study`` command."""
    p = subparsers.add_parser(
        "study",
        help="synthetic accuracy study (paper Table I, Fig. 7-8; static poses; duration)",
        description=_plain(__doc__.split("\n\n", 1)[1]),
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=POLICY_EPILOG,
    )
    p.add_argument("--out", required=True, help="output directory (created if missing)")
    p.add_argument("--config", help="study settings (TOML), e.g. pipelines/table1-study.toml")
    p.add_argument("--quick", action="store_true", help="the reduced study of the test suite")
    p.add_argument("--levels", type=int, help="log-spaced noise levels (plus 0.08 and 0.2)")
    p.add_argument("--sigma-min", type=float, help="lowest σ_n (m/s²)")
    p.add_argument("--sigma-max", type=float, help="highest σ_n (m/s²)")
    p.add_argument("--realisations", type=int, help="noise realisations per level (joint fit)")
    p.add_argument(
        "--paper-realisations", type=int, help="realisations per level for the paper's method"
    )
    p.add_argument("--static-realisations", type=int, help="static six-pose Monte Carlo runs")
    p.add_argument("--settle-s", type=float, help="settling time per static pose (s)")
    p.add_argument("--check-realisations", type=int, help="joint fits per duration/rate check")
    p.add_argument("--workers", type=int, help="worker processes (0 = every core)")
    p.add_argument("--seed", type=int, help="master seed")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    p.add_argument("--no-rrd", action="store_true", help="skip the Rerun recording")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.set_defaults(handler=run)


def command_line(args: argparse.Namespace) -> str:
    """The command that reproduces this run (for the outputs)."""
    parts = ["wheelcal", "study"]
    if args.config:
        parts += ["--config", args.config]
    if args.quick:
        parts.append("--quick")
    for option in _OVERRIDES:
        value = getattr(args, option)
        if value is not None:
            parts += [f"--{option.replace('_', '-')}", str(value)]
    parts += ["--out", args.out]
    parts += [
        flag for flag in ("--no-plots", "--no-rrd") if getattr(args, flag[2:].replace("-", "_"))
    ]
    return " ".join(shlex.quote(p) for p in parts)


class _Progress:
    """A bar on a terminal, a log line every 10 % otherwise (stderr)."""

    def __init__(self, stream=None) -> None:
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.start = time.monotonic()
        self.last_decile: dict[str, int] = {}

    def __call__(self, stage: str, done: int, total: int) -> None:
        elapsed = time.monotonic() - self.start
        if self.tty:
            width = 30
            filled = int(width * done / max(total, 1))
            bar = "#" * filled + "-" * (width - filled)
            end = "\n" if done == total else ""
            self.stream.write(f"\r{stage:>6} [{bar}] {done}/{total} {elapsed:5.0f} s{end}")
            self.stream.flush()
            return
        decile = int(10 * done / max(total, 1))
        if done == total or decile > self.last_decile.get(stage, 0):
            self.last_decile[stage] = decile
            self.stream.write(
                f"wheelcal study: {stage} {done}/{total} ({100 * done / max(total, 1):.0f} %), "
                f"{elapsed:.0f} s\n"
            )
            self.stream.flush()


def run(args: argparse.Namespace) -> int:
    """Run the study and write its outputs."""
    from pathlib import Path

    from wheelcal.cli.overwrite import claim
    from wheelcal.io import origin_of, output_mark
    from wheelcal.study import (
        StudyConfig,
        StudyConfigError,
        load_config,
        run_study,
        study_outputs,
        with_overrides,
        write_outputs,
    )

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: exists and is not a directory")
    try:
        if args.config:
            from wheelcal.cli.options import readable_inputs

            readable_inputs(("--config", args.config))  # a FIFO would wait forever
            if not Path(args.config).is_file():
                raise UsageError(f"--config {args.config}: no such file")
            config = load_config(args.config)
        else:
            config = StudyConfig()
        if args.quick:
            config = with_overrides(config, **QUICK)
        config = with_overrides(
            config, **{field: getattr(args, option) for option, field in _OVERRIDES.items()}
        )
    except StudyConfigError as exc:
        raise UsageError(str(exc)) from None

    # The study's input: its --config file (else the built-in settings); claimed first.
    inputs = (args.config,) if args.config else ()
    origin = origin_of(inputs, None if args.config else {"study": "built-in settings"})
    plots, rrd = not args.no_plots, not args.no_rrd
    claim(study_outputs(out, origin, inputs, plots, rrd), args.force, "study")
    progress = _Progress()
    command = command_line(args)
    sys.stderr.write(
        f"wheelcal study: {len(config.noise_sweep.sigma_levels_mps2())} noise levels, "
        f"{config.noise_sweep.realisations} joint / "
        f"{config.noise_sweep.realisations_of('paper')} paper-method runs each\n"
    )
    result = run_study(config, progress)
    written = write_outputs(
        result, out, command=command, plots=plots, rrd=rrd, mark=output_mark(origin, inputs)
    )
    sys.stderr.write(
        f"wheelcal study: {result.fits} fits in {result.wall_s:.0f} s on {result.workers} "
        f"workers; wrote {len(written)} files to {out}\n"
    )
    return 0
