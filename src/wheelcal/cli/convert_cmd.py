"""``wheelcal convert IN.csv OUT.mcap`` — a CSV accelerometer log into a contract MCAP."""

from __future__ import annotations

import argparse


def register(sub) -> None:
    """Add the ``convert`` parser."""
    p = sub.add_parser(
        "convert",
        help="convert a CSV log (time + three acceleration columns) into a contract MCAP",
        description=(
            "Read a CSV with a time column and three acceleration columns (by header name, "
            "or by 0-based index for files without a header) and write an MCAP that "
            "`wheelcal calibrate` reads, with the session facts as wheelcal.session metadata."
        ),
    )
    p.add_argument("source", metavar="IN.csv")
    p.add_argument("destination", metavar="OUT.mcap")
    p.add_argument("--time-column", default="t", help="header name or index (default t)")
    p.add_argument(
        "--accel-columns",
        nargs=3,
        default=["ax", "ay", "az"],
        metavar=("X", "Y", "Z"),
        help="header names or indices (default ax ay az)",
    )
    p.add_argument("--time-unit", choices=("s", "ms", "us", "ns"), default="s")
    p.add_argument(
        "--accel-unit", choices=("m/s^2", "g"), required=True, help="unit of the samples"
    )
    p.add_argument("--delimiter", help="default: detect , ; or tab")
    p.add_argument("--epoch-unix-ns", type=int, default=0, help="added to every time stamp")
    p.add_argument("--format", choices=("json", "ros2"), default="json", help="message encoding")
    p.add_argument("--radius", type=float, help="store radius_m in the session metadata")
    p.add_argument("--sensor-id")
    p.add_argument("--mounting-id")
    p.set_defaults(handler=run)


def _column(text: str) -> str | int:
    return int(text) if text.lstrip("-").isdigit() else text


def run(args: argparse.Namespace) -> int:
    """Convert and report."""
    from wheelcal.cli.errors import UsageError
    from wheelcal.io.csv_convert import CsvLayout, convert_csv

    try:
        layout = CsvLayout(
            time_column=_column(args.time_column),
            accel_columns=tuple(_column(c) for c in args.accel_columns),
            time_unit=args.time_unit,
            accel_unit=args.accel_unit,
            delimiter=args.delimiter,
            epoch_unix_ns=args.epoch_unix_ns,
        )
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    session = {
        k: str(v)
        for k, v in (
            ("radius_m", args.radius),
            ("sensor_id", args.sensor_id),
            ("mounting_id", args.mounting_id),
        )
        if v is not None
    }
    result = convert_csv(
        args.source, args.destination, layout, encoding=args.format, session=session
    )
    print(f"wrote {args.destination}: {result.samples} samples from {result.rows} rows")
    for note in result.notes:
        print(f"  note: {note}")
    return 0
