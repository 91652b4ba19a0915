"""The ``lean`` gate of a wheel in the field: what a camber the model does not follow would do.

A rolling wheel's camber follows the gyro's track or is one number
(:mod:`wheelcal.estimate.field.gyro_axle`'s ``CamberChoice``); its lean check
(:mod:`wheelcal.estimate.field.lean_check`) frees the camber on top of that and
reports what it would move.  The gate judges the answer, not the lean's size:

* nothing moves significantly and beyond its σ — the lean is modelled, whatever its size;
* only the axle axis's own gain and offset move (g sin γ is that axis's signal) —
  those are reported null with the reason, the rest calibrated;
* an in-plane gain or offset or the radius moves — refused by name (``lean``).

``--max-lean-change-deg`` (no limit by default) still refuses a camber that changes
by more than it, whatever it does.

The axle axis's offset is what the camber at the window's centre trades with (both
are a constant along the axle; only the turns' share of the camber tells them apart,
to 1–4° on a car's drive): where its σ exceeds ``Gates.field_axle_offset_std_mps2``
it is reported null with that reason (:func:`camber_nulls`).
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.field import FieldResult
from wheelcal.recording import CalibrationRefused
from wheelcal.session.gates import Gates


def axle_axis(field: FieldResult) -> str:
    """The sensor axis nearest the wheel's axle (bench Z in the sensor's frame: R e_Z)."""
    along = np.abs(field.result.params.bench.misalignment.matrix[:, 2])
    return "xyz"[int(np.argmax(along))]


def camber_nulls(field: FieldResult, gates: Gates) -> tuple[tuple[str, str], ...]:
    """The axle axis's offset null where the camber leaves it undetermined (module docstring)."""
    if field.geometry.kind != "rolling":
        return ()
    result = field.result
    name = f"offset_{axle_axis(field)}_mps2"
    std = result.std_of(name)
    limit = gates.field_axle_offset_std_mps2
    if std <= limit:
        return ()
    tilt = result.std_of("tilt_deg")
    return (
        (
            name,
            f"the camber at the window's centre trades with this axis's offset (both a "
            f"constant along the axle; the turns tell them apart to ± {tilt:.2g}°): σ = "
            f"{std:.3g} m/s², more than {limit:g} m/s²",
        ),
    )


def judge_the_lean(source: str, field: FieldResult, gates: Gates) -> tuple[tuple[str, str], ...]:
    """Apply the gate (module docstring); return the parameters it reports null, with why."""
    geometry = field.geometry
    if geometry.kind != "rolling":
        return ()
    lean = geometry.lean_change_deg
    if lean > gates.max_lean_change_deg:
        raise CalibrationRefused(
            source,
            "lean",
            f"the wheel's camber changes by {lean:.1f}° during the drive (the gyro reads the "
            "wheel rolling about the direction of travel), beyond the limit given",
            f"--max-lean-change-deg (now {gates.max_lean_change_deg:g}) sets the limit; "
            "without it the camber follows the gyro's track and the lean check judges it",
        )
    check = geometry.lean_check
    if check is None:
        return ()
    moved = check.moved(gates.lean_z, gates.lean_shift_sigma)
    if not moved:
        return ()
    axle = axle_axis(field)
    own = {f"gain_{axle}", f"offset_{axle}_mps2"}
    words = ", ".join(
        f"{n} by {check.shift_sigma[n]:.1f} σ (z = {check.shift_z[n]:.1f})" for n in moved
    )
    followed = geometry.camber is not None and geometry.camber.used
    how = "follows the gyro's track" if followed else "is one for the drive"
    if set(moved) <= own:
        reason = (
            f"the camber (which {how}) does not describe the axle axis's share of gravity: "
            f"a camber free to move would shift {words}"
        )
        return tuple((name, reason) for name in sorted(moved))
    raise CalibrationRefused(
        source,
        "lean",
        f"the wheel's camber does something the model does not follow (it {how}, changing "
        f"by {lean:.1f}°): a camber free to move would shift {words}",
        "calibrate from a drive on a flatter road or with a steadier carrier, or on a bench; "
        "--lean-z and --lean-shift-sigma set the check's limits",
    )
