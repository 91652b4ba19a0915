"""``wheelcal`` — the console script.

Each command lives in ``wheelcal/cli/<name>_cmd.py`` and exposes
``register(subparsers)``, which adds its parser and sets ``handler`` to a
function ``(args) -> int``.  Heavy imports happen inside the handlers, so
``wheelcal --help`` is instant.

BLAS runs single-threaded (see :func:`main`); batches and studies use worker
processes instead.

Exit status (CONTRACT): 0 success; 1 some sessions failed (the others still
ran, each failure is named); 2 bad usage.  Errors name the file and what is
wrong — never a bare traceback (``--debug`` shows one).
"""

from __future__ import annotations

import argparse
import importlib
import sys

from wheelcal import __version__
from wheelcal.cli.errors import CommandFailed, UsageError

#: Command modules, in the order ``--help`` lists them.
COMMANDS = (
    "simulate",
    "calibrate",
    "batch",
    "diagnose",
    "apply",
    "export",
    "convert",
    "plan",
    "study",
)


def _available_commands() -> list:
    modules = []
    for name in COMMANDS:
        try:
            modules.append(importlib.import_module(f"wheelcal.cli.{name}_cmd"))
        except ModuleNotFoundError as exc:
            if exc.name != f"wheelcal.cli.{name}_cmd":
                raise
    return modules


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser."""
    parser = argparse.ArgumentParser(
        prog="wheelcal",
        description=(
            "Calibrate a triaxial accelerometer with a tilted, hand-spun bicycle wheel "
            "(offsets, gains, and the bench it was never told about)."
        ),
        epilog=(
            "Exit status: 0 success, 1 some sessions failed (the others still ran), 2 bad usage. "
            "Every command and option: docs/guide/commands.md; frame and sign conventions and "
            "every output file (calibration/diagnosis JSON, report.json, .rrd): "
            "docs/guide/outputs.md; input formats: docs/guide/inputs.md."
        ),
    )
    parser.add_argument("--version", action="version", version=f"wheelcal {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in _available_commands():
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        # wheelcal's linear algebra is many small products (P ≈ 15–50 columns): BLAS
        # threads do not speed them up, and on a busy machine their spin-waiting
        # can make a fit 10–20× slower.  Parallelism comes from worker processes.
        from threadpoolctl import threadpool_limits

        from wheelcal.runtime import tune_allocator

        tune_allocator()  # large arrays stay in the heap (see wheelcal.runtime)
        with threadpool_limits(1):
            return int(args.handler(args) or 0)
    except UsageError as exc:
        print(f"wheelcal {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except CommandFailed as exc:
        print(f"wheelcal {args.command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("wheelcal: interrupted", file=sys.stderr)
        return 130
    except (OSError, ValueError, RuntimeError) as exc:
        if args.debug:
            raise
        from wheelcal.io import describe_error

        print(f"wheelcal {args.command}: error: {describe_error(exc)}", file=sys.stderr)
        return 1
    except Exception as exc:  # MemoryError and the unforeseen: a message, never a traceback
        if args.debug:
            raise
        print(
            f"wheelcal {args.command}: error: {type(exc).__name__}: {exc} "
            "(run with --debug for the traceback)",
            file=sys.stderr,
        )
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
