"""A CSV export read directly into a :class:`~wheelcal.recording.Recording` (no ``convert``).

CONTRACT: ``calibrate`` (and ``batch``, the API) read the CSV exports of IMU
loggers whose format states the units.  Those are:

* the **Xsens (Movella) DOT** CSV export, recognised by its header
  (``PacketCounter``, ``SampleTimeFine``, ``Acc_*``, ``Gyr_*``): the format fixes
  its units (:mod:`~wheelcal.io.csv_formats`);
* a CSV whose **header states every unit**: the time's (``Time (s)``,
  ``Timestamp (us)``, or a name that implies it: ``SampleTimeFine``, ``millis``,
  ``time_ms``), the accelerometer's, on columns named as an accelerometer's
  (``Accelerometer X (g)``, ``Acceleration x (m/s^2)``, ``Acc_X (m/s^2)``), and the
  gyro's when it has one (``Gyroscope X (deg/s)``) — x-io's NGIMU ``sensors.csv`` and
  x-IMU3 ``Inertial.csv``, phyphox's export.

Any other CSV — an Arduino log's ``millis,ax,ay,az`` in raw counts states no
unit — is refused, naming the file and what it does not say, with the
``wheelcal convert`` command that states it.  A unit is never guessed for a
direct read: ``convert`` infers a time unit from the sampling rate and says
so; here the format must state it.  ``accel_unit`` (``--accel-unit``) and
``gyro_unit`` state a unit the file does not, or replace one it states
wrongly, as for an MCAP file.

The samples then take the one way raw samples become a recording,
:meth:`Recording.from_samples <wheelcal.recording.Recording.from_samples>`
(its repairs and refusals: a logger's leading zero rows, NaNs, spikes,
duplicates, gaps), so a CSV read directly equals the same CSV converted and
read back, sample for sample.  A CSV has no topics and no ``wheelcal.session``
record: the session facts (the radius, …) come from the command line or the
pipeline, or are estimated (a field fit needs no radius).
"""

from __future__ import annotations

import dataclasses
import os
import re
from collections.abc import Mapping
from pathlib import Path

from wheelcal.io.csv_log import CsvLayout, CsvPlan, plan_csv_log, read_csv_log
from wheelcal.io.errors import InputError, TopicError
from wheelcal.io.session_meta import session_info
from wheelcal.recording import ACCEL_UNITS, GYRO_UNITS, InputPolicy, Recording, TemperatureReadings

#: Column names that say "accelerometer" (bare ``X (g)`` may be linear or earth acceleration).
_ACCELEROMETER = re.compile(r"^(?:a|acc|accel|accelerometer|acceleration)[\s._-]*[xyz]\b", re.I)


def looks_like_csv(head: bytes) -> bool:
    """Whether a file's first bytes are a delimited text table (not MCAP, JSON, binary).

    Only the bytes before a NUL count: a table followed by a hole (a sparse file) is a
    CSV, which the CSV reader refuses at its line.
    """
    head = head.split(b"\x00", 1)[0]
    if not head:
        return False
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 3:  # not a character cut at the end of the head
            return False
        text = head[: exc.start].decode("utf-8")
    for line in text.lstrip("\ufeff").splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        if line.lower().startswith(("sep=", '"sep=')):
            return True
        return not line.startswith(("{", "[")) and any(d in line for d in ",;\t")
    return False


def read_csv_recording(
    path: str | os.PathLike,
    topic: str | None = None,
    info_overrides: Mapping[str, object] | None = None,
    *,
    info_defaults: Mapping[str, object] | None = None,
    accel_unit: str | None = None,
    policy: InputPolicy | None = None,
    gravity_checked: bool = True,
    gyro: bool = True,
    gyro_unit: str | None = None,
    temperature: bool = True,
) -> Recording:
    """Read a CSV export whose format states its units (see the module docstring).

    The parameters are :func:`~wheelcal.io.mcap_reader.read_recording`'s; a CSV
    has no topics, so ``topic`` must be None.

    Raises
    ------
    InputError
        Naming the file: a CSV whose format does not state a unit (with the
        ``wheelcal convert`` command that does), what no sensor log is (see
        :mod:`~wheelcal.io.csv_table`), the checks of
        :meth:`~wheelcal.recording.Recording.from_samples`.
    """
    path = str(path)
    if topic is not None:
        raise TopicError(path, f"a CSV log has no topics (topic {topic!r} given); leave it out")
    if accel_unit is not None and accel_unit not in ACCEL_UNITS:
        raise InputError(path, f"unit {accel_unit!r} is not one of {list(ACCEL_UNITS)}")
    if gyro_unit is not None and gyro_unit not in GYRO_UNITS:
        raise InputError(path, f"gyro unit {gyro_unit!r} is not one of {list(GYRO_UNITS)}")
    layout = CsvLayout(read_gyro=gyro, check_units=False)
    plan = _stated(plan_csv_log(path, layout), accel_unit, gyro_unit)
    if not temperature:
        plan = dataclasses.replace(plan, cols=dataclasses.replace(plan.cols, temperature=None))
    info = session_info(path, [], info_overrides, info_defaults, gravity_forced=not gravity_checked)
    log = read_csv_log(plan, layout)
    readings = None
    if log.temperature_c is not None:
        column = log.conversion.columns["temperature"]
        readings = TemperatureReadings(f"column {column!r}", log.stamps_ns, log.temperature_c)
    return Recording.from_samples(
        source=path,
        time_ns=log.stamps_ns,
        accel=log.accel,
        unit=log.accel_unit,
        info=info,
        policy=policy,
        gyro=log.gyro,
        gyro_unit=log.gyro_unit,
        temperature=readings,
        topic="",
        notes=log.conversion.notes,
        label=path,
        unit_remedy=_remedy(log.accel_unit, given=accel_unit is not None),
        gyro_unit_hint=(
            f"the file states {log.gyro_unit}; if it is wrong, read it with gyro_unit=... "
            "(Python), or convert it with --gyro-unit"
        ),
        consume=True,
    )


def _remedy(unit: str, given: bool) -> str:
    """How to read the samples in the other unit, when the unit check refuses this one."""
    other = "g" if unit == "m/s^2" else "m/s^2"
    if given:
        return f"{unit} was given: give --accel-unit {other} (Python: accel_unit={other!r})"
    return (
        f"the file states {unit}; if that is wrong, read it with --accel-unit {other} "
        f"(Python: accel_unit={other!r})"
    )


def _stated(plan: CsvPlan, accel_unit: str | None, gyro_unit: str | None) -> CsvPlan:
    """The plan with the units given; refused when the file does not state one it needs."""
    notes = list(plan.notes)
    convert = f"wheelcal convert {plan.path} {Path(plan.path).with_suffix('.mcap').name}"
    names = [plan.header[i].strip() for i in plan.cols.accel]
    if plan.export is None and not all(_ACCELEROMETER.match(n) for n in names):
        raise InputError(
            plan.path,
            f"columns {names} are not named as an accelerometer's (Accelerometer X, Acc_X, "
            "ax, …): they may hold another acceleration (linear, or in the earth frame); if "
            f"they are the accelerometer's readings, convert it: {convert} --accel-columns "
            f"{' '.join(names)} --accel-unit …",
        )
    unit = accel_unit or plan.accel_unit
    rate = gyro_unit or plan.gyro_unit
    missing, options = [], []
    if plan.time_unit is None:
        missing.append(f"time unit (column {plan.header[plan.cols.time].strip()!r})")
        options.append("[--time-unit s|ms|us|ns: inferred from the rate when left out]")
    if unit is None:
        missing.append(f"acceleration unit (columns {names})")
        options.append("--accel-unit m/s^2|g|mg|counts [--counts-per-g N]")
    if plan.cols.gyro is not None and rate is None:
        gyros = [plan.header[i].strip() for i in plan.cols.gyro]
        missing.append(f"gyro unit (columns {gyros})")
        options.append("--gyro-unit rad/s|deg/s (or --no-gyro)")
    if missing:
        given = (
            "; or state it here: --accel-unit m/s^2|g (Python: accel_unit=)"
            if len(missing) == 1 and unit is None
            else ""
        )
        raise InputError(
            plan.path,
            f"the header states no {' and no '.join(missing)} (as 'Time (s)' and "
            "'Accelerometer X (g)' do), and a CSV is read directly only when its format states "
            f"every unit: convert it, {convert} {' '.join(options)}{given}",
        )
    if accel_unit is not None and plan.accel_unit not in (None, accel_unit):
        stated = plan.accel_unit
        notes.append(f"acceleration read in {accel_unit} as given (the file states {stated})")
    if gyro_unit is not None and plan.gyro_unit not in (None, gyro_unit):
        notes.append(f"gyro read in {gyro_unit} as given; the file states {plan.gyro_unit}")
    return dataclasses.replace(plan, accel_unit=unit, gyro_unit=rate, notes=tuple(notes))
