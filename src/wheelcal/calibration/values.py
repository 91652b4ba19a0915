"""The typed, frozen values a :class:`~wheelcal.calibration.document.Calibration` carries.

A calibration is one value from the fit to the file (imucal's ``CalibrationInfo``):
:class:`~wheelcal.calibration.document.Calibration` is built once from the contract
document — the one :func:`~wheelcal.calibration.session_json.calibration_dict` makes
of a :class:`~wheelcal.session.SessionResult`, or the one read back from a file — and
its fields are these values, parsed at construction, never again.  The same document
gives the same values in the process that computed it and in one that read it.

* :func:`sensor_fields`: offsets and gains with their statistical and systematic σ,
  what the recording could not determine, the correction a = M (v − b), the warnings
  (``sensor``, ``systematic``, ``correction``, ``fit.warnings``).
* :class:`CalibrationDiagnosis`: what the closed loop did to the paper's model — its
  level α, the effects it added with the score test that added each
  (:class:`AddedEffect`), what it tested and what it could not
  (``fit.effects_screen``, ``effects.<name>.evidence``).
* the lean (``bench.lean``): :class:`~wheelcal.session.LeanReport`, the session's own
  type, read back from the document.

Values JSON holds as ``null`` (undetermined, not finite) are NaN in the arrays and
None in the scalars.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from wheelcal.estimate.joint import FreedCheck
from wheelcal.model import SensorCorrection
from wheelcal.session import CamberTrackReport, LeanReport


def frozen_array(values) -> np.ndarray:
    """A read-only float array of JSON numbers (null → NaN)."""
    out = np.array([np.nan if v is None else float(v) for v in values], dtype=float)
    out.setflags(write=False)
    return out


def _nan_array(size: int = 3) -> np.ndarray:
    out = np.full(size, np.nan)
    out.setflags(write=False)
    return out


def _optional(value) -> float | None:
    return None if value is None else float(value)


def _optional_map(values: Mapping) -> Mapping:
    """A read-only name → float-or-None mapping of a JSON object."""
    return MappingProxyType({k: _optional(v) for k, v in values.items()})


def sensor_fields(document: Mapping) -> dict:
    """The sensor's numbers of a calibration document (a session's or a sensor's), parsed once.

    ``sensor``, ``systematic``, ``correction`` and ``fit.warnings``: ``gain``,
    ``offset_mps2`` and their statistical and systematic σ (read-only arrays, NaN where
    undetermined; NaN σ in a document without them, the smallest usable sensor
    document), ``undetermined`` ((parameter, reason) pairs), ``correction``
    (a = M (v − b), identity rows on undetermined axes) and ``warnings``.
    """
    sensor = document["sensor"]
    systematic = document.get("systematic", {})
    block = document["correction"]

    def std(mapping: Mapping, key: str) -> np.ndarray:
        return frozen_array(mapping[key]) if key in mapping else _nan_array()

    return {
        "gain": frozen_array(sensor["gain"]),
        "offset_mps2": frozen_array(sensor["offset_mps2"]),
        "gain_std": std(sensor, "gain_std"),
        "offset_std_mps2": std(sensor, "offset_std_mps2"),
        "systematic_gain_std": std(systematic, "gain_std"),
        "systematic_offset_std_mps2": std(systematic, "offset_std_mps2"),
        "undetermined": tuple(
            (u["parameter"], u["reason"]) for u in sensor.get("undetermined", ())
        ),
        "correction": SensorCorrection(bias_mps2=block["bias_mps2"], matrix=block["matrix"]),
        "warnings": tuple(document.get("fit", {}).get("warnings", ())),
    }


@dataclass(frozen=True)
class AddedEffect:
    """An effect the closed loop added, and the score test at the model before it."""

    name: str
    statistic: float | None
    dof: int
    p_value: float | None
    #: Bonferroni over the candidates of its step.
    p_corrected: float | None
    #: "spin" (the accelerometer's stream), "spin+rests", or with the gyro's.
    streams: str


@dataclass(frozen=True)
class CalibrationDiagnosis:
    """What the closed loop did to the paper's model (``fit.effects_screen``), typed.

    ``steps`` are the effects added, with their evidence, in the order the model
    lists them; ``added`` their labels in the order the loop added them.  ``tested``
    the effects screened on the final model (``with_rests``: those also tested on the
    rests), ``not_identifiable`` those the recording's own parameters can mimic, and
    ``smallest_p_corrected`` the final screen's smallest family-wise p (None: none
    tested).  None on a :class:`~wheelcal.calibration.document.Calibration` whose fit
    had no closed loop (``model="paper"``, a wheel in the field).
    """

    model: str
    alpha: float
    added: tuple[str, ...]
    steps: tuple[AddedEffect, ...]
    tested: tuple[str, ...]
    with_rests: tuple[str, ...]
    not_identifiable: tuple[str, ...]
    smallest_p_corrected: float | None

    @classmethod
    def from_document(cls, document: Mapping) -> CalibrationDiagnosis | None:
        """Parse ``fit.effects_screen`` and the effects' ``evidence`` (None: no screen)."""
        fit = document.get("fit", {})
        screen = fit.get("effects_screen")
        if screen is None:
            return None
        steps = tuple(
            AddedEffect(
                name=name,
                statistic=_optional(e["statistic"]),
                dof=int(e["dof"]),
                p_value=_optional(e["p_value"]),
                p_corrected=_optional(e["p_corrected"]),
                streams=str(e["streams"]),
            )
            for name, entry in document.get("effects", {}).items()
            if (e := entry.get("evidence")) is not None
        )
        return cls(
            model=str(fit.get("model", "closed_loop")),
            alpha=float(screen["alpha"]),
            added=tuple(screen["added"]),
            steps=steps,
            tested=tuple(screen["tested"]),
            with_rests=tuple(screen["with_rests"]),
            not_identifiable=tuple(screen["not_identifiable"]),
            smallest_p_corrected=_optional(screen["smallest_p_corrected"]),
        )


def lean_from_document(document: Mapping) -> LeanReport | None:
    """``bench.lean`` as the session's :class:`~wheelcal.session.LeanReport` (None: no lean).

    The check comes back as a :class:`~wheelcal.estimate.joint.FreedCheck` (its
    ``alternative`` stays in the document); its per-parameter shifts are read-only.
    """
    lean = document.get("bench", {}).get("lean")
    if lean is None:
        return None
    track = lean.get("track")
    check = lean.get("check")
    return LeanReport(
        change_deg=_optional(lean["change_deg"]),
        in_turns_deg_per_mps2=_optional(lean.get("in_turns_deg_per_mps2")),
        in_turns_std_deg_per_mps2=_optional(lean.get("in_turns_std_deg_per_mps2")),
        in_turns_deg=_optional(lean.get("in_turns_deg")),
        track=None
        if track is None
        else CamberTrackReport(
            followed=bool(track["followed"]),
            gyro_range_deg=_optional(track["gyro_range_deg"]),
            beyond_gyro_errors_deg=_optional(track["beyond_gyro_errors_deg"]),
            reason=str(track["reason"]),
        ),
        check=None
        if check is None
        else FreedCheck(
            statistic=_optional(check["statistic"]),
            dof=int(check["dof"]),
            p_value=_optional(check["p_value"]),
            shift_sigma=_optional_map(check["shift_sigma"]),
            shift_z=_optional_map(check["shift_z"]),
            spacing_s=float(check["knot_spacing_s"]),
        ),
    )
