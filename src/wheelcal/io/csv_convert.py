"""Convert a CSV IMU log into a contract MCAP (``wheelcal convert``).

The log is read by :mod:`~wheelcal.io.csv_log` (its rules: columns
recognised, units stated or given and checked, times exact, bounded memory)
and written by :func:`~wheelcal.io.mcap_writer.write_accel_mcap`, atomically
(complete or absent).  Defects a recording may have — NaNs, duplicate or
unordered stamps — are carried over for
:func:`~wheelcal.io.mcap_reader.read_recording` to repair or refuse, in one
place with one set of rules.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

from wheelcal.io.atomic import refuse_existing
from wheelcal.io.csv_log import CsvConversion, CsvLayout, plan_csv_log, read_csv_log
from wheelcal.io.mcap_writer import Compression, Encoding, write_accel_mcap

__all__ = ["CsvConversion", "CsvLayout", "convert_csv"]


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
    replace: bool = False,
    metadata: Mapping[str, Mapping[str, str]] | None = None,
) -> CsvConversion:
    """Convert a CSV IMU log into a contract MCAP file.

    Parameters
    ----------
    csv_path:
        The CSV log.
    mcap_path:
        Output file (written atomically).
    layout:
        Columns and units (:class:`CsvLayout`); by default every column is
        recognised by name and the time unit inferred.
    encoding:
        ``"json"`` (``wheelcal.AccelBatch``, ``batch_size`` samples per
        message, units kept as given) or ``"ros2"`` (``sensor_msgs/msg/Imu``;
        g → m/s² and deg/s → rad/s, as the message requires; a temperature
        goes to a ``sensor_msgs/msg/Temperature`` topic).
    batch_size:
        Samples per JSON message.
    topic:
        Output topic (default per encoding).
    session:
        ``wheelcal.session`` values to store, e.g. ``{"radius_m": "0.28"}``.
    compression:
        Chunk compression.
    replace:
        Replace an existing ``mcap_path`` (default ``False``: refused with
        :class:`~wheelcal.io.atomic.OutputExistsError` before the CSV is read,
        and again at the atomic install).
    metadata:
        More metadata records for the MCAP (``wheelcal convert`` adds its mark,
        :mod:`wheelcal.io.ownership`).

    Returns
    -------
    CsvConversion
        Row counts, the columns and time unit used, and notes on anything
        skipped, inferred or repaired.

    Raises
    ------
    InputError
        Missing or unreadable file, no data rows, unknown or ambiguous
        columns, an implausible or ambiguous time unit, a stated unit the
        data contradict — always naming the file.
    """
    layout = layout or CsvLayout()
    if not replace:
        refuse_existing(mcap_path)
    log = read_csv_log(plan_csv_log(csv_path, layout), layout, encoding)
    write_accel_mcap(
        mcap_path,
        log.stamps_ns,
        log.accel,
        encoding=encoding,
        topic=topic,
        batch_size=batch_size,
        unit=log.accel_unit,
        compression=compression,
        session=dict(session or {}),
        gyro=log.gyro,
        gyro_unit=log.gyro_unit,
        temperature_c=log.temperature_c,
        replace=replace,
        metadata=metadata,  # e.g. the wheelcal.output mark (io/ownership.py)
    )
    return log.conversion
