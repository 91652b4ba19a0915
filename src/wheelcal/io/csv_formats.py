"""CSV exports whose format fixes the units though their header states none (Xsens DOT).

Most exporters that state their units put them in the header
(``Accelerometer X (g)``: x-io's NGIMU ``sensors.csv`` and x-IMU3
``Inertial.csv``, phyphox's ``Acceleration x (m/s^2)``), which
:mod:`~wheelcal.io.csv_log` reads.  The Movella (Xsens) DOT's CSV export does
not: its header is ``PacketCounter,SampleTimeFine,…,Acc_X,…,Gyr_X,…`` and its
format fixes the units — ``SampleTimeFine`` in µs (a 32-bit counter of the
sensor's clock, which wraps after 71.6 min), ``Acc_*`` the calibrated
acceleration in m/s², ``Gyr_*`` the angular velocity in deg/s.  The format is
recognised by its header (``PacketCounter`` and ``SampleTimeFine``) and the
units taken from it, with a note saying so.

Its payloads differ (the DOT app's measurement modes, the SDK's export
columns).  Those with the accelerometer's readings (``Acc_*``, with or without
``Gyr_*``; Euler angles, quaternions, ``Mag_*``, ``Status`` and the rest beside
them) are read.  Those without are refused by name, for they hold no reading
a calibration can use: orientation only (``Quat_*``, ``Euler_*``), free
acceleration (``FreeAcc_*``: gravity removed by the sensor's filter, in the
earth frame) and delta quantities (``dq_*``, ``dv[*]``: integrated over each
interval in a turning frame).  ``PacketCounter`` (16 or 32 bits, wrapping)
counts the packets the sensor sent; a jump is a packet lost on the way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wheelcal.io.errors import InputError

XSENS_DOT = "Xsens DOT CSV export"


@dataclass(frozen=True)
class ExportFormat:
    """An exporter's format, recognised by its header, and the units it fixes."""

    name: str
    time_column: str
    time_unit: str
    accel_unit: str
    gyro_unit: str
    #: The packet counter column, for lost packets (or None).
    counter_column: str | None
    note: str


def _key(name: str) -> str:
    return name.strip().strip('"').strip().lower()


def export_format(path: str, header: Sequence[str]) -> ExportFormat | None:
    """The exporter format ``header`` is, or None; one without accelerometer readings refused.

    Raises
    ------
    InputError
        An Xsens DOT export without ``Acc_X``, ``Acc_Y``, ``Acc_Z``, saying what it has.
    """
    keys = {_key(h): h.strip() for h in header}
    if not {"packetcounter", "sampletimefine"} <= keys.keys():
        return None
    has = {prefix: all(f"{prefix}_{a}" in keys for a in "xyz") for prefix in ("acc", "gyr")}
    if not has["acc"]:
        raise InputError(path, _without_acc(keys))
    units = "Acc_* in m/s²" + (", Gyr_* in deg/s" if has["gyr"] else "")
    return ExportFormat(
        name=XSENS_DOT,
        time_column=keys["sampletimefine"],
        time_unit="us",
        accel_unit="m/s^2",
        gyro_unit="deg/s",
        counter_column=keys["packetcounter"],
        note=(
            f"{XSENS_DOT} (recognised by its header: PacketCounter, SampleTimeFine, Acc_*): "
            f"units as the format fixes them, SampleTimeFine in µs, {units}"
        ),
    )


def _without_acc(keys: dict[str, str]) -> str:
    """Why an Xsens DOT export without Acc_* cannot be calibrated, and what to export."""
    what = []
    if any(k.startswith("freeacc_") for k in keys):
        what.append(
            "free acceleration (FreeAcc_*: gravity removed by the sensor's orientation filter, "
            "in the earth frame)"
        )
    if any(k.startswith(("dq_", "dv[", "dv_")) for k in keys):
        what.append(
            "delta quantities (dq_*, dv[*]: integrated over each sample interval, in a "
            "frame that turns with the wheel)"
        )
    if any(k.startswith(("quat_", "euler_")) for k in keys):
        what.append("orientation (Quat_*/Euler_*)")
    if any(k.startswith("gyr_") for k in keys):
        what.append("angular velocity (Gyr_*)")
    listing = ", ".join(what) if what else f"only {sorted(keys.values())}"
    return (
        f"an {XSENS_DOT} without the accelerometer's readings (Acc_X, Acc_Y, Acc_Z): it holds "
        f"{listing}; nothing in it measures the specific force a calibration needs — record "
        "or export a payload with acceleration (Acc_*) and angular velocity (Gyr_*)"
    )


def lost_packets(counter: np.ndarray) -> tuple[int, int]:
    """Packets lost (and the places) from a packet counter that wraps at 2¹⁶ or 2³².

    A step of one is the next packet; a step of ``k`` (modulo the counter's
    range) is ``k - 1`` packets lost; a repeat (step 0) or a step back of more
    than half the range is no loss this can count (a restart).
    """
    c = counter[np.isfinite(counter)].astype(np.int64)
    if c.size < 2:
        return 0, 0
    span = 1 << 16 if c.max() < (1 << 16) else 1 << 32
    step = np.diff(c) % span
    lost = step[(step > 1) & (step < span // 2)] - 1
    return int(lost.sum()), int(lost.size)
