"""A CSV IMU log read: its columns recognised, its units found and checked, its times exact.

What ``wheelcal convert`` writes into an MCAP (:mod:`~wheelcal.io.csv_convert`) and
what ``calibrate`` reads directly (:mod:`~wheelcal.io.csv_recording`).  The file
is read in bounded memory, block by block (:mod:`~wheelcal.io.csv_table`, which
also refuses what no sensor log is: FIFOs, devices, huge files, endless lines,
binary data, thousands of columns).

A CSV log has a time column, three acceleration columns and optionally
three gyro columns and a temperature column.  Real exports (a logger, a
phone app, a vendor's tool, a spreadsheet) are read as they come:

* an Excel ``sep=,`` first line sets the delimiter and is skipped; otherwise
  the delimiter is the one of ``,`` ``;`` tab the header uses most;
  ``#`` comment lines and blank lines are skipped; a trailing empty column
  (every line ending in the delimiter) is ignored;
* columns are chosen by header name or 0-based index, or **recognised** by
  name, case-insensitively, ignoring a unit in brackets (``Acc_X (m/s^2)``)
  and spaces, dots and dashes (read as ``_``): time ``t``, ``time``,
  ``timestamp``, ``SampleTimeFine``, … (optionally with a unit suffix,
  ``time_ms``); acceleration ``ax``, ``acc_x``, ``Acc_X``, ``accel_x``,
  ``acceleration_x``, …; gyro ``gx``, ``gyr_x``, ``Gyr_X``, ``gyro_x``, …;
  temperature ``temp``, ``temperature``.  Two columns recognised for one
  role are an error that names them (choose with the options);
* the time unit (s, ms, us, ns) is taken as given, else from the column
  name (``SampleTimeFine`` is µs, ``time_ms`` is ms, ``Time (s)`` is s),
  else inferred from the data: the unit whose implied sampling rate is
  plausible — and refused when no unit, or more than one, gives a rate
  between 1 Hz and 100 kHz with one of them the typical 10 Hz – 10 kHz, or
  when the given unit implies a rate outside 1 Hz – 100 kHz (almost surely
  the wrong unit).  A Unix epoch's magnitude breaks ties;
* an integer time that wraps like a 32-bit counter (a drop by more than
  2³¹ counts, values in [0, 2³²)) is unwrapped;
* the acceleration unit is as given, else as the header states it in
  brackets (phyphox's ``Acceleration x (m/s^2)``; ``g``, ``mg``); a file that
  states none needs it given.  Raw integer counts are read with
  ``counts`` and their scale (``counts_per_g``, e.g. 16384 for a 16-bit
  sensor at ±2 g), mg as g/1000; both are written as g;
* the unit is checked against the data: at rest (quiet stretches) |a| must
  be ≈ 1 g in that unit (integers that read like 16384 or 4096 at rest are
  named as raw counts, with the option that reads them); the gyro unit
  likewise (rad/s beyond 4000 °/s is deg/s), from the header too
  (``Gyroscope x (rad/s)``);
* decimal commas (``9,81``; phyphox's and Excel's semicolon CSV in many
  locales) are read when the delimiter is not a comma;
* Arduino's ``millis`` and ``micros`` columns are time in ms and µs;
* an exporter format that fixes its units without stating them (the Xsens DOT
  CSV export, :mod:`~wheelcal.io.csv_formats`) gives them, with a note.

Times are converted to integer nanoseconds *exactly* from their decimal text
(no float rounding of absolute Unix times); ``epoch_unix_ns`` is added, for
logs whose time starts at zero.  Other defects — NaNs, duplicate or unordered
stamps — are carried over for :func:`~wheelcal.io.mcap_reader.read_recording`
to repair or refuse, in one place with one set of rules.  Rows whose time is
not a number are skipped (and counted); an empty cell becomes NaN; any other
non-numeric cell is an error (the columns or the delimiter are wrong).  Every
error names the file.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from wheelcal.io.csv_formats import ExportFormat, export_format, lost_packets
from wheelcal.io.csv_table import TableColumns, TableHead, open_table, read_table
from wheelcal.io.errors import InputError
from wheelcal.model import STANDARD_GRAVITY_MPS2
from wheelcal.recording import rest_level

TIME_UNITS_NS = {"s": 1_000_000_000, "ms": 1_000_000, "us": 1_000, "ns": 1}
ACCEL_UNITS = ("m/s^2", "g", "mg", "counts")
#: Raw counts per g of common MEMS ranges: 16-bit at ±2/4/8/16 g, 12- and 10-bit parts.
COUNTS_PER_G = (16384, 8192, 4096, 2048, 1024, 512, 256)
#: Units a header may state in brackets, e.g. phyphox's ``Acceleration x (m/s^2)``.
_HEADER_ACCEL_UNITS = {
    "m/s^2": "m/s^2",
    "m/s²": "m/s^2",
    "m/s2": "m/s^2",
    "m/s/s": "m/s^2",
    "m s^-2": "m/s^2",
    "ms^-2": "m/s^2",
    "g": "g",
    "mg": "mg",
}
_HEADER_GYRO_UNITS = {
    "rad/s": "rad/s",
    "rad s^-1": "rad/s",
    "deg/s": "deg/s",
    "°/s": "deg/s",
    "dps": "deg/s",
}
GYRO_UNITS = ("rad/s", "deg/s")
#: Sampling rates a time unit may imply; outside, the unit is almost surely wrong.
PLAUSIBLE_RATE_HZ = (1.0, 100_000.0)
#: Rates IMU logs actually use (to choose between two plausible units).
TYPICAL_RATE_HZ = (10.0, 10_000.0)
MAX_GYRO_DPS = 4000.0

_UNIT_ALIASES = {
    "s": "s",
    "sec": "s",
    "secs": "s",
    "second": "s",
    "seconds": "s",
    "ms": "ms",
    "msec": "ms",
    "millis": "ms",
    "milliseconds": "ms",
    "us": "us",
    "µs": "us",
    "μs": "us",
    "usec": "us",
    "micros": "us",
    "microseconds": "us",
    "ns": "ns",
    "nsec": "ns",
    "nanoseconds": "ns",
}
_TIME_NAMES = (  # by priority; the unit a name implies, or None
    ("t", None),
    ("time", None),
    ("timestamp", None),
    ("time_stamp", None),
    ("millis", "ms"),  # Arduino's millis()
    ("micros", "us"),  # Arduino's micros()
    ("sampletimefine", "us"),  # Xsens: 1 MHz ticks of the device clock, 32-bit
    ("sample_time_fine", "us"),
    ("seconds_elapsed", "s"),
    ("elapsed", None),
    ("elapsed_time", None),
)
_UNIT_SUFFIX = "|".join(sorted(_UNIT_ALIASES, key=len, reverse=True))
_TIME_WITH_UNIT = re.compile(rf"^(t|time|timestamp|time_stamp|elapsed)_({_UNIT_SUFFIX})$")
_ACCEL = re.compile(r"^(?:a|acc|accel|accelerometer|acceleration)_?([xyz])$")
_GYRO = re.compile(r"^(?:g|gyr|gyro|gyroscope|w|omega|angular_velocity|ang_vel)_?([xyz])$")
_TEMPERATURE = re.compile(r"^(?:temp|temperature)(?:_c|_degc)?$")
_BRACKET_UNIT = re.compile(r"\s*[\(\[]([^\)\]]*)[\)\]]\s*$")

Column = str | int


@dataclass(frozen=True)
class CsvLayout:
    """Where the data are in the CSV and in which units.

    Columns are header names, or 0-based indices for a file without a
    header; ``None`` recognises them by name (see the module docstring).
    ``time_unit=None`` infers it; ``delimiter=None`` detects one of
    ``,`` ``;`` tab.  ``accel_unit=None`` takes the unit the header states
    (``Acceleration x (m/s^2)``) and refuses a file that states none;
    ``"counts"`` needs ``counts_per_g`` (raw integers: 16384 for a 16-bit
    sensor at ±2 g); ``"mg"`` is g/1000.  Gyro columns are read when given or
    recognised, unless ``read_gyro=False``; their unit ``gyro_unit`` must then
    be stated, or be in the header.
    """

    time_column: Column | None = None
    accel_columns: tuple[Column, Column, Column] | None = None
    time_unit: str | None = None
    accel_unit: str | None = None
    delimiter: str | None = None
    epoch_unix_ns: int = 0
    gyro_columns: tuple[Column, Column, Column] | None = None
    gyro_unit: str | None = None
    read_gyro: bool = True
    temperature_column: Column | None = None
    check_units: bool = True
    counts_per_g: float | None = None
    #: The gyro columns are raw counts, this many per °/s (``gyro_unit`` ``"counts"`` or
    #: unset): converted to °/s.
    gyro_counts_per_dps: float | None = None

    def __post_init__(self) -> None:
        if self.time_unit is not None and self.time_unit not in TIME_UNITS_NS:
            raise ValueError(f"time_unit must be one of {list(TIME_UNITS_NS)}")
        if self.accel_unit is not None and self.accel_unit not in ACCEL_UNITS:
            raise ValueError(f"accel_unit must be one of {list(ACCEL_UNITS)}")
        if (self.accel_unit == "counts") != (self.counts_per_g is not None):
            raise ValueError(
                "raw counts need their scale: accel_unit 'counts' with counts_per_g "
                "(--accel-unit counts --counts-per-g N), and counts_per_g only with counts"
            )
        if self.counts_per_g is not None and not (
            np.isfinite(self.counts_per_g) and self.counts_per_g > 0
        ):
            raise ValueError(f"counts_per_g must be positive, got {self.counts_per_g!r}")
        if self.gyro_unit is not None and self.gyro_unit not in (*GYRO_UNITS, "counts"):
            raise ValueError(f"gyro_unit must be one of {[*GYRO_UNITS, 'counts']}")
        counts = self.gyro_counts_per_dps
        if (self.gyro_unit == "counts" and counts is None) or (
            counts is not None and self.gyro_unit not in (None, "counts")
        ):
            raise ValueError(
                "raw gyro counts need their scale: --gyro-counts-per-dps N (gyro_unit 'counts' "
                f"or unset), got gyro_unit {self.gyro_unit!r} with {counts!r} counts per °/s"
            )
        if counts is not None and not (np.isfinite(counts) and counts > 0):
            raise ValueError(f"gyro_counts_per_dps must be positive, got {counts!r}")
        for name in ("accel_columns", "gyro_columns"):
            value = getattr(self, name)
            if value is not None and len(value) != 3:
                raise ValueError(f"{name} needs exactly three columns (x, y, z)")
        given = [self.time_column, self.temperature_column]
        given += list(self.accel_columns or ()) + list(self.gyro_columns or ())
        kinds = {isinstance(c, int) for c in given if c is not None}
        if len(kinds) > 1:
            raise ValueError("give all columns by name or all by index, not a mix")
        if kinds == {True} and (self.time_column is None or self.accel_columns is None):
            raise ValueError("a file without a header needs the time and acceleration indices")

    @property
    def by_index(self) -> bool:
        """Whether the file has no header (columns given by index)."""
        return isinstance(self.time_column, int)


@dataclass(frozen=True)
class CsvConversion:
    """What :func:`convert_csv` did: counts, the columns and units used, and notes."""

    rows: int
    samples: int
    skipped_rows: int
    notes: tuple[str, ...]
    columns: Mapping[str, object] = field(default_factory=dict)
    time_unit: str = "s"
    rate_hz: float = 0.0


def _normalise(name: str) -> tuple[str, str | None]:
    """A header name as a lower-case key (``Acc_X (m/s^2)`` → ``acc_x``) and its bracketed unit."""
    text = name.strip().strip('"').strip()
    unit = None
    match = _BRACKET_UNIT.search(text)
    if match:
        unit = match.group(1).strip().lower()
        text = text[: match.start()]
    key = re.sub(r"[\s.\-]+", "_", text.lower()).strip("_")
    return key, unit


def _find(path: str, header: list[str], wanted: Column, role: str) -> int:
    """The index of an explicitly given column (exact name, else case-insensitive)."""
    if isinstance(wanted, int):
        if not 0 <= wanted < len(header):
            raise InputError(
                path, f"column index {wanted} out of range (the file has {len(header)})"
            )
        return wanted
    names = [h.strip() for h in header]
    if wanted in names:
        return names.index(wanted)
    folded = [i for i, name in enumerate(names) if name.lower() == wanted.lower()]
    if len(folded) == 1:
        return folded[0]
    raise InputError(path, f"no {role} column {wanted!r}; the header has {names}")


def _recognise(path: str, header: list[str], pattern: re.Pattern, role: str) -> list[int] | None:
    """Columns x, y, z whose names match ``pattern``; None if not all three are there."""
    found: dict[str, list[int]] = {"x": [], "y": [], "z": []}
    for i, name in enumerate(header):
        match = pattern.match(_normalise(name)[0])
        if match:
            found[match.group(1)].append(i)
    if not any(found.values()):
        return None
    for axis, where in found.items():
        if len(where) > 1:
            names = [header[i].strip() for i in where]
            raise InputError(
                path,
                f"several {role} columns for {axis}: {names}; choose with --{role}-columns",
            )
    if not all(found.values()):
        missing = next(axis for axis, where in found.items() if not where)
        # Name the column the others suggest: ax, ay → az; Acc_X, Acc_Y → Acc_Z.
        model = _BRACKET_UNIT.sub("", header[next(w[0] for w in found.values() if w)]).strip()
        at = max(model.rfind(c) for c in "xyzXYZ")
        letter = missing.upper() if model[at].isupper() else missing
        stem = model[:at] + letter + model[at + 1 :]
        raise InputError(
            path,
            f"no column {stem!r} ({role} {missing}); the header has {[h.strip() for h in header]}",
        )
    return [found[a][0] for a in "xyz"]


def _time_column(path: str, header: list[str]) -> tuple[int, str | None]:
    """The recognised time column and the unit its name implies."""
    keys = [_normalise(h) for h in header]
    for name, unit in _TIME_NAMES:
        where = [i for i, (key, _) in enumerate(keys) if key == name]
        if len(where) > 1:
            raise InputError(
                path,
                f"several time columns {[header[i].strip() for i in where]}; "
                "choose one with --time-column",
            )
        if where:
            bracket = keys[where[0]][1]
            return where[0], unit or _UNIT_ALIASES.get(bracket or "")
    for i, (key, _) in enumerate(keys):
        match = _TIME_WITH_UNIT.match(key)
        if match:
            return i, _UNIT_ALIASES[match.group(2)]
    raise InputError(
        path,
        "no time column recognised (t, time, timestamp, SampleTimeFine, …); the header has "
        f"{[h.strip() for h in header]}; name it with --time-column",
    )


def _temperature_column(header: list[str]) -> int | None:
    where = [i for i, h in enumerate(header) if _TEMPERATURE.match(_normalise(h)[0])]
    return where[0] if len(where) == 1 else None


@dataclass(frozen=True)
class _Columns:
    time: int
    accel: list[int]
    gyro: list[int] | None
    temperature: int | None
    time_unit_hint: str | None


def _columns(path: str, header: list[str], layout: CsvLayout) -> _Columns:
    hint = None
    if layout.time_column is None:
        time, hint = _time_column(path, header)
    else:
        time = _find(path, header, layout.time_column, "time")
        if isinstance(layout.time_column, str):
            key, bracket = _normalise(header[time])
            match = _TIME_WITH_UNIT.match(key)
            hint = _UNIT_ALIASES[match.group(2)] if match else _UNIT_ALIASES.get(bracket or "")
            hint = hint or dict(_TIME_NAMES).get(key)
    if layout.accel_columns is None:
        accel = _recognise(path, header, _ACCEL, "accel")
        if accel is None:
            bare = [[i for i, h in enumerate(header) if _normalise(h)[0] == a] for a in "xyz"]
            if not all(len(b) == 1 for b in bare):
                raise InputError(
                    path,
                    "no acceleration columns recognised (ax/acc_x/Acc_X/accel_x …); the header "
                    f"has {[h.strip() for h in header]}; name them with --accel-columns",
                )
            accel = [b[0] for b in bare]
    else:
        accel = [_find(path, header, c, "acceleration") for c in layout.accel_columns]
    gyro = None
    if layout.read_gyro:
        if layout.gyro_columns is not None:
            gyro = [_find(path, header, c, "gyro") for c in layout.gyro_columns]
        elif not layout.by_index:
            gyro = _recognise(path, header, _GYRO, "gyro")
    temperature = None
    if layout.temperature_column is not None:
        temperature = _find(path, header, layout.temperature_column, "temperature")
    elif not layout.by_index:
        temperature = _temperature_column(header)
    return _Columns(time, accel, gyro, temperature, hint)


def _g_in_unit(unit: str, counts_per_g: float | None) -> float:
    """What 1 g (9.80665 m/s²) reads in ``unit``."""
    return {"m/s^2": STANDARD_GRAVITY_MPS2, "g": 1.0, "mg": 1000.0}.get(unit) or float(
        counts_per_g or 1.0
    )


def _unit_name(unit: str, counts_per_g: float | None) -> str:
    return f"counts ({counts_per_g:g} per g)" if unit == "counts" else unit


def _check_accel_unit(
    path: str, accel: np.ndarray, unit: str, counts_per_g: float | None = None
) -> str | None:
    """Refuse a stated unit the data contradict (|a| at rest ≈ 1 g); a note on what was seen."""
    g_in_unit = _g_in_unit(unit, counts_per_g)
    rest = rest_level(accel)
    if rest is None:
        return "no quiet stretch to check the acceleration unit against (|a| at rest = 1 g)"
    ratio = rest / g_in_unit
    if 0.8 < ratio < 1.25:
        return None
    guesses = {"g": 1.0, "m/s^2": STANDARD_GRAVITY_MPS2, "mg": 1000.0}
    fixes = {name: f"--accel-unit {name}" for name in guesses}
    finite = accel[np.all(np.isfinite(accel), axis=1)]
    if finite.size and np.all(finite == np.round(finite)):  # integers: raw ADC counts?
        for n in COUNTS_PER_G:
            guesses[f"raw counts at {n} per g"] = float(n)
            fixes[f"raw counts at {n} per g"] = f"--accel-unit counts --counts-per-g {n}"
    guess = [name for name, level in guesses.items() if 0.8 < rest / level < 1.25]
    if guess:
        options = "; or ".join(fixes[g] for g in guess)
        looks = f": the data look like {' or '.join(guess)} ({options})"
    else:
        looks = (
            "; raw integer counts? give their scale: --accel-unit counts --counts-per-g N "
            "(N = counts per g of the sensor's range, e.g. 16384 for a 16-bit sensor at ±2 g)"
        )
    raise InputError(
        path,
        f"at rest the samples read |a| = {rest:.4g}, but 1 g is {g_in_unit:g} "
        f"{_unit_name(unit, counts_per_g)}{looks}; the acceleration unit is stated wrongly",
    )


def _header_unit(
    path: str, header: list[str], where: list[int], table: dict[str, str], what: str
) -> str | None:
    """The unit the headers of ``where`` state in brackets (all the same), or None."""
    stated = [_normalise(header[i])[1] for i in where]
    if not any(stated):
        return None
    units = {table.get(u) for u in stated}
    if len(units) != 1 or None in units:
        raise InputError(
            path,
            f"the {what} columns state units {stated} in their headers; state the unit with "
            f"--{what}-unit",
        )
    return units.pop()


def _accel_unit(
    path: str,
    header: list[str],
    cols: _Columns,
    layout: CsvLayout,
    export: ExportFormat | None,
    notes: list[str],
) -> str | None:
    """The acceleration unit: as given, else as the header (or format) states it; None if none.

    A given unit that contradicts the one the header or the format states is refused.
    """
    stated = (
        None
        if layout.by_index
        else _header_unit(path, header, cols.accel, _HEADER_ACCEL_UNITS, "accel")
    )
    source = "the header"
    if stated is None and export is not None:
        stated, source = export.accel_unit, f"the {export.name} format"
    if layout.accel_unit is None:
        if stated is not None:
            notes.append(f"acceleration unit {stated} from {source}")
        return stated
    if stated is not None and stated != layout.accel_unit:
        raise InputError(
            path,
            f"{source} states the acceleration in {stated}, but {layout.accel_unit} was "
            "given; remove one of the two",
        )
    return layout.accel_unit


def _check_gyro_unit(path: str, gyro: np.ndarray, unit: str) -> None:
    finite = gyro[np.all(np.isfinite(gyro), axis=1)]
    if unit != "rad/s" or finite.size == 0:
        return
    peak = float(np.max(np.abs(finite)))
    if np.degrees(peak) > MAX_GYRO_DPS:
        raise InputError(
            path,
            f"the gyro columns read up to {peak:.4g}, beyond any MEMS gyroscope in rad/s "
            f"(±{MAX_GYRO_DPS:g} °/s = {np.radians(MAX_GYRO_DPS):.4g} rad/s): they look like "
            "deg/s (--gyro-unit deg/s)",
        )


def _stated_gyro_unit(
    path: str,
    header: list[str],
    cols: _Columns,
    layout: CsvLayout,
    export: ExportFormat | None,
    notes: list[str],
) -> str | None:
    """The gyro columns' unit, as given or as the header (or format) states it; None if none."""
    if layout.gyro_counts_per_dps is not None:
        return "counts"
    if cols.gyro is None or layout.gyro_unit is not None:
        return layout.gyro_unit
    if not layout.by_index:
        gyro_unit = _header_unit(path, header, cols.gyro, _HEADER_GYRO_UNITS, "gyro")
        if gyro_unit is not None:
            notes.append(f"gyro unit {gyro_unit} from the header")
            return gyro_unit
    if export is not None:
        notes.append(f"gyro unit {export.gyro_unit} from the {export.name} format")
        return export.gyro_unit
    return None


def _accel_for_output(
    path: str,
    accel: np.ndarray,
    accel_unit: str,
    layout: CsvLayout,
    encoding: str,
    notes: list[str],
) -> tuple[np.ndarray, str]:
    """The samples checked against their unit, in g or m/s² (m/s² for ROS 2), and that unit."""
    if layout.check_units:
        seen = _check_accel_unit(path, accel, accel_unit, layout.counts_per_g)
        if seen:
            notes.append(seen)
    if accel_unit in ("mg", "counts"):  # the contract carries g or m/s²
        accel /= _g_in_unit(accel_unit, layout.counts_per_g)
        notes.append(f"converted {_unit_name(accel_unit, layout.counts_per_g)} to g")
        accel_unit = "g"
    if encoding == "ros2" and accel_unit == "g":
        accel *= STANDARD_GRAVITY_MPS2
        accel_unit = "m/s^2"
        notes.append("converted g to m/s^2 (sensor_msgs/msg/Imu carries m/s^2)")
    return accel, accel_unit


def _gyro_for_output(
    path: str,
    gyro: np.ndarray | None,
    gyro_unit: str,
    layout: CsvLayout,
    encoding: str,
    notes: list[str],
) -> tuple[np.ndarray | None, str]:
    """The gyro rows checked against their unit (rad/s for ROS 2), and that unit."""
    if gyro_unit == "counts":
        if gyro is None:
            return None, "rad/s"
        gyro = gyro / layout.gyro_counts_per_dps
        gyro_unit = "deg/s"
        notes.append(f"converted gyro counts to °/s ({layout.gyro_counts_per_dps:g} per °/s)")
    if gyro is not None and layout.check_units:
        _check_gyro_unit(path, gyro, gyro_unit)
    if encoding == "ros2" and gyro is not None and gyro_unit == "deg/s":
        gyro = np.radians(gyro)
        gyro_unit = "rad/s"
        notes.append("converted deg/s to rad/s (sensor_msgs/msg/Imu carries rad/s)")
    return gyro, gyro_unit


def _column_names(header: list[str], cols: _Columns, layout: CsvLayout) -> dict[str, object]:
    """The columns used, by role: header names (or indices for a file without a header)."""
    names = {
        "time": cols.time,
        "accel": cols.accel,
        "gyro": cols.gyro,
        "temperature": cols.temperature,
    }
    if layout.by_index:
        return names
    return {
        role: (
            None
            if where is None
            else [header[i].strip() for i in where]
            if isinstance(where, list)
            else header[where].strip()
        )
        for role, where in names.items()
    }


def _unwrap_counter(whole: np.ndarray, pico: np.ndarray, notes: list[str], name: str) -> None:
    """Undo, in place, the wraps of a 32-bit integer counter (drops by more than 2³¹ counts)."""
    if whole.size < 2 or np.any(pico) or whole.min() < 0 or whole.max() >= 2**32:
        return
    wraps = np.diff(whole) < -(2**31)
    if not np.any(wraps):
        return
    whole[1:] += np.cumsum(wraps) * 2**32
    notes.append(f"unwrapped {int(wraps.sum())} wrap(s) of the 32-bit counter {name!r}")


def _median_step(whole: np.ndarray, pico: np.ndarray) -> float:
    """The median positive step between times, from their exact parts (no absolute float).

    From at most ~100k steps, evenly spread, as the sample checks take theirs
    (a long log's full diff would be temporaries of 40 B per row for the same median).
    """
    if whole.size > 200_001:
        at = np.arange(0, whole.size - 1, (whole.size - 1) // 100_000)
        whole = np.stack([whole[at], whole[at + 1]], axis=1)
        pico = np.stack([pico[at], pico[at + 1]], axis=1)
    else:
        whole = np.stack([whole[:-1], whole[1:]], axis=1)
        pico = np.stack([pico[:-1], pico[1:]], axis=1)
    steps = np.diff(whole, axis=1)[:, 0].astype(float) + np.diff(pico, axis=1)[:, 0] * 1e-12
    steps = steps[steps > 0]
    return float(np.median(steps)) if steps.size else 0.0


def _rates(step: float) -> dict[str, float]:
    return {unit: 1e9 / (step * scale) for unit, scale in TIME_UNITS_NS.items()}


def _choose_time_unit(
    path: str, name: str, step: float, first: float, given: str | None, hint: str | None
) -> tuple[str, float, str]:
    """The time unit, the implied rate and how it was chosen; refusal if implausible."""
    if step <= 0:
        raise InputError(path, f"the time column {name!r} does not advance")
    rates = _rates(step)
    lo, hi = PLAUSIBLE_RATE_HZ
    plausible = [u for u, r in rates.items() if lo <= r <= hi]

    def alternatives() -> str:
        others = [f"{u}: {rates[u]:.4g} Hz" for u in plausible]
        return f"; with --time-unit {' or '.join(others)}" if others else ""

    chosen = given or hint
    if chosen is not None:
        rate = rates[chosen]
        if not lo <= rate <= hi:
            how = "as given" if given else "as its name says"
            raise InputError(
                path,
                f"the time column {name!r} in {chosen} ({how}) implies a sampling rate of "
                f"{rate:.4g} Hz, not plausible ({lo:g} Hz … {hi:g} Hz): almost surely the "
                f"wrong time unit{alternatives()}",
            )
        return chosen, rate, "given" if given else f"from the column name {name!r}"
    epoch = [u for u in plausible if 1e9 <= first * TIME_UNITS_NS[u] * 1e-9 <= 4.2e9]
    typical = [u for u in plausible if TYPICAL_RATE_HZ[0] <= rates[u] <= TYPICAL_RATE_HZ[1]]
    for candidates, why in (
        (epoch, "Unix time"),
        (plausible, "the only plausible rate"),
        (typical, "the only typical rate"),
    ):
        if len(candidates) == 1:
            unit = candidates[0]
            return unit, rates[unit], f"inferred ({why}: median step {step:g})"
    listing = ", ".join(f"{u}: {r:.4g} Hz" for u, r in rates.items())
    if not plausible:
        raise InputError(
            path,
            f"the time column {name!r} (median step {step:g}) implies no plausible sampling "
            f"rate in any unit ({listing}); is it a time?",
        )
    raise InputError(
        path,
        f"the time unit of column {name!r} is ambiguous (median step {step:g}: {listing}); "
        "state it with --time-unit",
    )


def _stamps_ns(
    path: str, name: str, table: TableColumns, plan: CsvPlan, layout: CsvLayout, notes: list[str]
) -> tuple[np.ndarray, str, float]:
    """Integer ns stamps, exactly from the decimal times; the time unit and the rate it implies.

    The times' whole parts become the stamps in place; a fraction is rounded to the
    nearest ns, half to even (as decimal arithmetic rounds).
    """
    whole, pico = table.time_whole, table.time_pico
    _unwrap_counter(whole, pico, notes, name)
    first = float(whole[0]) + float(pico[0]) * 1e-12
    unit, rate_hz, how = _choose_time_unit(
        path, name, _median_step(whole, pico), first, layout.time_unit, plan.cols.time_unit_hint
    )
    if how != "given":
        notes.append(f"time unit {unit} {how}: {rate_hz:.4g} Hz")
    scale = TIME_UNITS_NS[unit]
    limit = (2**63 - 1 - abs(layout.epoch_unix_ns)) // scale - 1
    if max(abs(int(whole.min())), abs(int(whole.max()))) > limit:
        raise InputError(
            path,
            f"the time column {name!r} in {unit} reaches beyond the range of int64 "
            "nanoseconds (year 2262): a wrong time unit or column?",
        )
    per_ns = 10**12 // scale  # pico units of the time unit in one ns
    has_fraction = bool(np.any(pico))
    for at in range(0, whole.size, 1 << 16):  # in pieces: temporaries of 64 Ki rows
        part = whole[at : at + (1 << 16)]
        part *= scale
        if has_fraction:
            ns_of, rest = np.divmod(pico[at : at + (1 << 16)], per_ns)
            part += ns_of
            part += (2 * rest > per_ns) | ((2 * rest == per_ns) & (part % 2 == 1))
        part += layout.epoch_unix_ns
    return whole, unit, rate_hz


@dataclass(frozen=True)
class CsvPlan:
    """What a CSV log holds, decided before its data are read: columns and stated units."""

    path: str
    head: TableHead
    #: The header's names (for a file without one, ``""`` per cell).
    header: tuple[str, ...]
    cols: _Columns
    export: ExportFormat | None
    #: The acceleration unit given or stated (header or format); None when neither.
    accel_unit: str | None
    #: The gyro unit given or stated; None when neither (or no gyro columns).
    gyro_unit: str | None
    #: The time unit given, or the one the column's name (or the format) implies.
    time_unit: str | None
    notes: tuple[str, ...]


def plan_csv_log(path: str | os.PathLike, layout: CsvLayout) -> CsvPlan:
    """Open a CSV log and find its columns and the units it states (no data read yet)."""
    path = str(path)
    head = open_table(path, layout.delimiter, has_header=not layout.by_index)
    notes = list(head.notes)
    header = list(head.header) if not layout.by_index else [""] * head.cells
    export = None if layout.by_index else export_format(path, header)
    if export is not None:
        notes.append(export.note)
        if layout.time_column is None:  # the format's clock, whatever else the header holds
            layout = replace(layout, time_column=export.time_column)
    cols = _columns(path, header, layout)
    accel_unit = _accel_unit(path, header, cols, layout, export, notes)
    gyro_unit = _stated_gyro_unit(path, header, cols, layout, export, notes)
    return CsvPlan(
        path=path,
        head=head,
        header=tuple(header),
        cols=cols,
        export=export,
        accel_unit=accel_unit,
        gyro_unit=gyro_unit,
        time_unit=layout.time_unit or cols.time_unit_hint,
        notes=tuple(notes),
    )


@dataclass(frozen=True, eq=False)
class CsvLog:
    """A CSV log read: its samples in the units the output carries, and the report."""

    stamps_ns: np.ndarray
    accel: np.ndarray
    accel_unit: str
    gyro: np.ndarray | None
    gyro_unit: str
    temperature_c: np.ndarray | None
    conversion: CsvConversion


def require_units(plan: CsvPlan, *, accel: bool = True) -> None:
    """Refuse a log whose gyro (and, with ``accel``, acceleration) unit is unknown."""
    if accel and plan.accel_unit is None:
        raise InputError(
            plan.path,
            "the acceleration unit is not stated (neither in the header, e.g. "
            "'Acceleration x (m/s^2)', nor given): give --accel-unit m/s^2, g, mg, or "
            "counts with --counts-per-g N",
        )
    if plan.cols.gyro is not None and plan.gyro_unit is None:
        raise InputError(
            plan.path,
            f"gyro columns {_names(plan, plan.cols.gyro)} found: state their unit (--gyro-unit "
            "rad/s or deg/s), or leave them out (--no-gyro)",
        )


def _names(plan: CsvPlan, where: list[int]) -> list[str] | list[int]:
    return [plan.header[i].strip() for i in where] if any(plan.header) else where


def read_csv_log(plan: CsvPlan, layout: CsvLayout, encoding: str = "json") -> CsvLog:
    """The log's samples, units converted as the contract and ``encoding`` need, and the report.

    ``plan`` comes from :func:`plan_csv_log` with the same ``layout`` and its
    units known (:func:`require_units`: the gyro's refused before the data are read,
    the acceleration's after, as a data error is the likelier mistake); ``encoding``
    ``"ros2"`` converts g to m/s² and deg/s to rad/s.
    """
    require_units(plan, accel=False)
    path, cols, notes = plan.path, plan.cols, list(plan.notes)
    groups: dict[str, list[int]] = {"accel": cols.accel}
    if cols.gyro is not None:
        groups["gyro"] = cols.gyro
    if cols.temperature is not None:
        groups["temperature"] = [cols.temperature]
    counter = None
    if plan.export is not None and plan.export.counter_column in plan.header:
        counter = plan.header.index(plan.export.counter_column)
        groups["counter"] = [counter]
    names = [h if h.strip() else f"#{i}" for i, h in enumerate(plan.header)]
    table = read_table(plan.head, cols.time, groups, names)
    time_name = names[cols.time].strip() if not layout.by_index else f"#{cols.time}"
    stamps, unit, rate_hz = _stamps_ns(path, time_name, table, plan, layout, notes)
    groups, rows, skipped, odd = table.groups, table.rows, table.skipped, table.odd_rows
    del table  # the times' fractions go
    require_units(plan)
    accel, accel_unit = _accel_for_output(
        path, groups["accel"], plan.accel_unit, layout, encoding, notes
    )
    gyro, gyro_unit = _gyro_for_output(
        path, groups.get("gyro"), plan.gyro_unit or "rad/s", layout, encoding, notes
    )
    if counter is not None:
        lost, places = lost_packets(groups["counter"])
        if lost:
            notes.append(
                f"{plan.header[counter]}: {lost} packet(s) missing in {places} place(s), samples "
                "lost on the way (their gaps keep their real times)"
            )
    if skipped:
        notes.append(f"skipped {skipped} rows without a numeric time")
    if odd:
        notes.append(
            f"{odd} rows have another number of cells than the first data row (read cell by cell)"
        )
    conversion = CsvConversion(
        rows=rows,
        samples=stamps.size,
        skipped_rows=skipped,
        notes=tuple(notes),
        columns=_column_names(list(plan.header), cols, layout),
        time_unit=unit,
        rate_hz=rate_hz,
    )
    temperature = groups.get("temperature")
    return CsvLog(stamps, accel, accel_unit, gyro, gyro_unit, temperature, conversion)
