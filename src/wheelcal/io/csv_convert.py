"""Convert a CSV accelerometer log into a contract MCAP (``wheelcal convert``).

A CSV log has a time column and three acceleration columns, chosen by header
name or by 0-based index, with a time unit (s, ms, us, ns) and an
acceleration unit (m/s^2 or g).  Times are converted to integer nanoseconds
*exactly* from their decimal text (no float rounding of absolute Unix
times); ``epoch_unix_ns`` is added, for logs whose time starts at zero.

The data are carried over faithfully — defects such as NaNs, duplicate or
unordered stamps are left for :func:`~wheelcal.io.mcap_reader.read_recording`
to repair or refuse, so that happens in one place with one set of rules.
Rows whose time is not a number are skipped (and counted); an empty
acceleration cell becomes NaN; any other non-numeric acceleration cell is an
error (it means the columns or the delimiter are wrong).  The output is
written atomically.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Mapping
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from wheelcal.io.errors import InputError
from wheelcal.io.mcap_writer import Compression, Encoding, write_accel_mcap
from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2

TIME_UNITS_NS = {"s": 1_000_000_000, "ms": 1_000_000, "us": 1_000, "ns": 1}
ACCEL_UNITS = ("m/s^2", "g")


@dataclass(frozen=True)
class CsvLayout:
    """Where the data are in the CSV and in which units.

    ``time_column`` and ``accel_columns`` are header names, or 0-based
    indices for a file without a header.  ``delimiter=None`` detects one of
    ``,`` ``;`` tab.
    """

    time_column: str | int = "t"
    accel_columns: tuple[str | int, str | int, str | int] = ("ax", "ay", "az")
    time_unit: str = "s"
    accel_unit: str = "m/s^2"
    delimiter: str | None = None
    epoch_unix_ns: int = 0

    def __post_init__(self) -> None:
        if self.time_unit not in TIME_UNITS_NS:
            raise ValueError(f"time_unit must be one of {list(TIME_UNITS_NS)}")
        if self.accel_unit not in ACCEL_UNITS:
            raise ValueError(f"accel_unit must be one of {list(ACCEL_UNITS)}")
        if len(self.accel_columns) != 3:
            raise ValueError("accel_columns needs exactly three columns (x, y, z)")
        kinds = {isinstance(c, int) for c in (self.time_column, *self.accel_columns)}
        if len(kinds) != 1:
            raise ValueError("give all columns by name or all by index, not a mix")


@dataclass(frozen=True)
class CsvConversion:
    """What :func:`convert_csv` did."""

    rows: int
    samples: int
    skipped_rows: int
    notes: tuple[str, ...]


def _to_ns(text: str, scale: int) -> int:
    """Exact integer nanoseconds from a decimal time string."""
    value = Decimal(text.strip()) * scale
    if not value.is_finite():
        raise InvalidOperation
    return int(value.to_integral_value())


def _to_float(text: str) -> float:
    """A number; an empty cell is NaN (a gap the reader reports); other text is an error."""
    if not text.strip():
        return float("nan")
    return float(text)


def _columns(path: str, header: list[str], layout: CsvLayout) -> list[int]:
    wanted = [layout.time_column, *layout.accel_columns]
    if isinstance(layout.time_column, int):
        width = len(header)
        bad = [c for c in wanted if not 0 <= c < width]  # type: ignore[operator]
        if bad:
            raise InputError(path, f"column index {bad[0]} out of range (the file has {width})")
        return [int(c) for c in wanted]
    names = [h.strip() for h in header]
    missing = [c for c in wanted if c not in names]
    if missing:
        raise InputError(path, f"no column {missing[0]!r}; the header has {names}")
    return [names.index(c) for c in wanted]  # type: ignore[arg-type]


def convert_csv(
    csv_path: str | os.PathLike,
    mcap_path: str | os.PathLike,
    layout: CsvLayout | None = None,
    *,
    encoding: Encoding = "json",
    batch_size: int = 50,
    topic: str | None = None,
    session: Mapping[str, str] | None = None,
    compression: Compression = "zstd",
) -> CsvConversion:
    """Convert a CSV accelerometer log into a contract MCAP file.

    Parameters
    ----------
    csv_path:
        The CSV log.
    mcap_path:
        Output file (written atomically).
    layout:
        Columns and units (:class:`CsvLayout`).
    encoding:
        ``"json"`` (``wheelcal.AccelBatch``, ``batch_size`` samples per
        message, unit kept as given) or ``"ros2"`` (``sensor_msgs/msg/Imu``;
        g is converted to m/s², as the message requires).
    batch_size:
        Samples per JSON message.
    topic:
        Output topic (default per encoding).
    session:
        ``wheelcal.session`` values to store, e.g. ``{"radius_m": "0.28"}``.
    compression:
        Chunk compression.

    Returns
    -------
    CsvConversion
        Row counts and notes on anything skipped.

    Raises
    ------
    InputError
        Missing or unreadable file, no data rows, unknown columns.
    """
    layout = layout or CsvLayout()
    path = str(csv_path)
    try:
        text = Path(csv_path).read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"cannot be read as text ({exc})") from None
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")]
    if not lines:
        raise InputError(path, "the CSV file has no data")
    delimiter = layout.delimiter or max((",", ";", "\t"), key=lines[0].count)
    rows = list(csv.reader(io.StringIO("\n".join(lines)), delimiter=delimiter))
    by_index = isinstance(layout.time_column, int)
    header = rows[0]
    body = rows if by_index else rows[1:]
    if not body:
        raise InputError(path, "the CSV file has a header but no data rows")
    cols = _columns(path, header, layout)
    scale = TIME_UNITS_NS[layout.time_unit]
    stamps: list[int] = []
    values: list[list[float]] = []
    skipped = 0
    first_line = 1 if by_index else 2
    for line, row in enumerate(body, start=first_line):
        try:
            stamp = _to_ns(row[cols[0]], scale)
        except (IndexError, InvalidOperation, ValueError):
            skipped += 1
            continue
        try:
            sample = [_to_float(row[c]) for c in cols[1:]]
        except (IndexError, ValueError):
            raise InputError(
                path, f"data row {line}: an acceleration cell is not a number: {row!r}"
            ) from None
        stamps.append(stamp + layout.epoch_unix_ns)
        values.append(sample)
    if not stamps:
        raise InputError(path, f"none of the {len(body)} rows has a numeric time")
    accel = np.array(values, dtype=float)
    unit = layout.accel_unit
    notes = []
    if encoding == "ros2" and unit == "g":
        accel = accel * STANDARD_GRAVITY_MPS2
        unit = "m/s^2"
        notes.append("converted g to m/s^2 (sensor_msgs/msg/Imu carries m/s^2)")
    if skipped:
        notes.append(f"skipped {skipped} rows without a numeric time")
    write_accel_mcap(
        mcap_path,
        np.array(stamps, dtype=np.int64),
        accel,
        encoding=encoding,
        topic=topic,
        batch_size=batch_size,
        unit=unit,
        compression=compression,
        session=dict(session or {}),
    )
    return CsvConversion(
        rows=len(body), samples=len(stamps), skipped_rows=skipped, notes=tuple(notes)
    )
