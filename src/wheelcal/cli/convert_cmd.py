"""``wheelcal convert IN.csv OUT.mcap`` — a CSV IMU log into a contract MCAP."""

from __future__ import annotations

import argparse
from pathlib import Path

from wheelcal.cli.overwrite import FORCE_HELP, POLICY_EPILOG

#: The command's one-line help and its --help description.
HELP = "convert a CSV log (time, acceleration, optional gyro) into a contract MCAP"
DESCRIPTION = (
    "Read a CSV with a time column, three acceleration columns and optionally three "
    "gyro columns and a temperature column, and write an MCAP that `wheelcal calibrate` "
    "reads, with the session facts as wheelcal.session metadata. Columns are "
    "recognised by name (t/time/timestamp/SampleTimeFine, ax/acc_x/Acc_X/accel_x, "
    "gx/gyr_x/Gyr_X/gyro_x, temp/temperature; any case) unless given, an Excel "
    "'sep=,' line and a trailing empty column are skipped, a wrapping 32-bit counter is "
    "unwrapped, and the time unit is inferred when not given (refused when the "
    "sampling rate it implies is implausible); Arduino's millis/micros are ms/µs. The "
    "acceleration unit comes from the header when it states one (phyphox: "
    "'Acceleration x (m/s^2)'), else it must be given; raw counts need "
    "--counts-per-g; the Xsens DOT export's format fixes its units (no options needed). "
    "Decimal commas (9,81) are read in ;-separated files. The file is read in bounded "
    "memory, and a FIFO, device, folder, a file over 2 GiB, NUL bytes, a line over 128 KiB "
    "or more than 256 columns are refused by name. An existing OUT.mcap is never replaced "
    "unless --force. (calibrate reads a CSV export directly when its format states every "
    "unit: Xsens DOT, x-io NGIMU/x-IMU3, phyphox.)"
)


def register(sub) -> None:
    """Add the ``convert`` parser."""
    p = sub.add_parser("convert", help=HELP, description=DESCRIPTION, epilog=POLICY_EPILOG)
    p.add_argument("source", metavar="IN.csv")
    p.add_argument("destination", metavar="OUT.mcap")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--time-column", help="header name or 0-based index (default: recognised)")
    _xyz_columns(p, "--accel-columns", "header names or indices (default: recognised)")
    p.add_argument(
        "--time-unit",
        choices=("s", "ms", "us", "ns"),
        help="default: from the column name, else inferred from the sampling rate",
    )
    p.add_argument(
        "--accel-unit",
        choices=("m/s^2", "g", "mg", "counts"),
        help="unit of the acceleration (default: as the header states it, e.g. "
        "'Acceleration x (m/s^2)'; needed when it states none); counts = raw integers, "
        "with --counts-per-g",
    )
    p.add_argument(
        "--counts-per-g",
        type=float,
        metavar="N",
        help="raw counts per g with --accel-unit counts (e.g. 16384 for a 16-bit sensor at "
        "±2 g, 4096 at ±8 g)",
    )
    _xyz_columns(
        p, "--gyro-columns", "header names or indices of the gyro (default: recognised if present)"
    )
    p.add_argument(
        "--gyro-unit",
        choices=("rad/s", "deg/s", "counts"),
        help="unit of the gyro (default: as the header states it; needed with a gyro otherwise); "
        "counts = raw integers, with --gyro-counts-per-dps",
    )
    p.add_argument(
        "--gyro-counts-per-dps",
        type=float,
        metavar="N",
        help="the gyro columns are raw counts, N per °/s (e.g. 131 for an MPU-6050/9250 at "
        "±250 °/s, 16.4 at ±2000 °/s): converted to °/s (rad/s in ROS 2)",
    )
    p.add_argument("--no-gyro", action="store_true", help="leave gyro columns out")
    p.add_argument("--temperature-column", help="°C column (default: recognised if present)")
    p.add_argument("--delimiter", help="default: an Excel sep= line, else detect , ; or tab")
    p.add_argument("--epoch-unix-ns", type=int, default=0, help="added to every time stamp")
    p.add_argument("--format", choices=("json", "ros2"), default="json", help="message encoding")
    p.add_argument(
        "--radius",
        type=radius_metres,
        metavar="M",
        help="the sensor's distance from the axle in metres (e.g. 0.28), stored as radius_m",
    )
    p.add_argument("--sensor-id", help="sensor identifier stored in the file (for reports)")
    p.add_argument("--mounting-id", help="mounting identifier stored in the file (for reports)")
    p.add_argument(
        "--gyro-full-scale-dps", type=float, help="store gyro_full_scale_dps (the gyro's range)"
    )
    p.set_defaults(handler=run)


def _xyz_columns(p, flag: str, text: str) -> None:
    """A sensor's three columns (x, y, z): header names or 0-based indices."""
    p.add_argument(flag, nargs=3, metavar=("X", "Y", "Z"), help=text)


#: No wheel puts its sensor farther from the axle than this (m): 280 is millimetres.
MAX_RADIUS_M = 2.0


def radius_metres(text: str) -> float:
    """An argparse type: a radius in metres, positive and at most :data:`MAX_RADIUS_M`."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number (metres)") from None
    if not (value > 0 and value <= MAX_RADIUS_M):
        hint = f" (in millimetres? {value / 1000:g} m)" if value > MAX_RADIUS_M else ""
        raise argparse.ArgumentTypeError(
            f"{text} m is not a sensor–axle distance: give metres, above 0 and at most "
            f"{MAX_RADIUS_M:g}{hint}"
        )
    return value


def _column(text: str | None) -> str | int | None:
    if text is None:
        return None
    return int(text) if text.lstrip("-").isdigit() else text


def run(args: argparse.Namespace) -> int:
    """Convert and report."""
    from wheelcal.cli.errors import UsageError
    from wheelcal.cli.options import readable_inputs
    from wheelcal.cli.overwrite import claim
    from wheelcal.io import MARK_RECORD, CsvLayout, Output, convert_csv, origin_of, output_mark

    readable_inputs(("IN.csv", args.source))  # a FIFO would wait forever, /dev/zero never end
    origin = origin_of([args.source])
    output = Output(Path(args.destination), origin, (args.source,))
    exists = claim([output], args.force, "convert")  # before reading the CSV

    def triple(values):
        return None if values is None else tuple(_column(c) for c in values)

    try:
        layout = CsvLayout(
            time_column=_column(args.time_column),
            accel_columns=triple(args.accel_columns),
            time_unit=args.time_unit,
            accel_unit=args.accel_unit,
            counts_per_g=args.counts_per_g,
            delimiter=args.delimiter,
            epoch_unix_ns=args.epoch_unix_ns,
            gyro_columns=triple(args.gyro_columns),
            gyro_unit=args.gyro_unit,
            gyro_counts_per_dps=args.gyro_counts_per_dps,
            read_gyro=not args.no_gyro,
            temperature_column=_column(args.temperature_column),
        )
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    session = {
        k: str(v)
        for k, v in (
            ("radius_m", args.radius),
            ("sensor_id", args.sensor_id),
            ("mounting_id", args.mounting_id),
            ("gyro_full_scale_dps", args.gyro_full_scale_dps),
        )
        if v is not None
    }
    result = convert_csv(
        args.source,
        args.destination,
        layout,
        encoding=args.format,
        session=session,
        replace=exists,
        metadata={MARK_RECORD: output_mark(origin, [args.source])},
    )
    used = ", ".join(f"{role} {cols}" for role, cols in result.columns.items() if cols is not None)
    print(
        f"wrote {args.destination}: {result.samples} samples from {result.rows} rows "
        f"({result.rate_hz:.4g} Hz; columns: {used})"
    )
    for note in result.notes:
        print(f"  note: {note}")
    return 0
