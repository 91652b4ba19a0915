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
* :class:`CalibrationFacts`: the source, bench and fit figures (``source``, ``bench``,
  ``fit``, ``parameters``, the effects' settings).

Each is written back by its own inverse (:func:`write_sensor_fields`,
:meth:`CalibrationDiagnosis.write_into`, :func:`lean_block`,
:meth:`CalibrationFacts.write_into`): the session's document
(:func:`~wheelcal.calibration.session_json.calibration_dict`) takes the diagnosis' and
the lean's blocks from them, and a ``Calibration``'s ``to_dict`` writes every field so.

Values JSON holds as ``null`` (undetermined, not finite) are NaN in the arrays and
None in the scalars.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from wheelcal.io import json_safe
from wheelcal.model import SensorCorrection
from wheelcal.session import CamberTrackReport, LeanReport


def json_number(x) -> float | None:
    """JSON-safe float: ∞/NaN become null (JSON has neither)."""
    x = float(x)
    return x if math.isfinite(x) else None


def json_numbers(values) -> list:
    """A flat list of JSON-safe floats (NaN → null)."""
    return [json_number(v) for v in np.asarray(values, dtype=float).reshape(-1)]


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


def write_sensor_fields(document: dict, fields) -> None:
    """Write :func:`sensor_fields`' values (attributes of ``fields``) into ``document``.

    The inverse of :func:`sensor_fields` on the entries the document has: a σ the
    document leaves out (the smallest sensor document) stays out.
    """
    sensor = document["sensor"]
    sensor["gain"] = json_numbers(fields.gain)
    sensor["offset_mps2"] = json_numbers(fields.offset_mps2)
    for key, name in (("gain_std", "gain_std"), ("offset_std_mps2", "offset_std_mps2")):
        if key in sensor:
            sensor[key] = json_numbers(getattr(fields, name))
    if "undetermined" in sensor:
        sensor["undetermined"] = [{"parameter": p, "reason": r} for p, r in fields.undetermined]
    systematic = document.get("systematic")
    for key, name in (
        ("gain_std", "systematic_gain_std"),
        ("offset_std_mps2", "systematic_offset_std_mps2"),
    ):
        if systematic is not None and key in systematic:
            systematic[key] = json_numbers(getattr(fields, name))
    block = document["correction"]
    block["bias_mps2"] = json_numbers(fields.correction.bias_mps2)
    block["matrix"] = [json_numbers(row) for row in fields.correction.matrix]
    if "warnings" in document.get("fit", {}):
        document["fit"]["warnings"] = list(fields.warnings)


#: ``fit.effects_screen.correction``: how the screen's p are corrected.
SCREEN_CORRECTION = "Bonferroni over the candidates tested (each τ grid point counts)"
#: ``effects.<name>.evidence.test``: the test that added an effect.
EVIDENCE_TEST = "score (Lagrange multiplier) test at the model before it was added"


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
    def from_loop(cls, loop, model: str) -> CalibrationDiagnosis | None:
        """What the document keeps of the closed loop's report (None: no closed loop).

        ``loop`` is the :class:`~wheelcal.closedloop.Diagnosis`; ``steps`` follow the
        loop's order here (the document lists them in the model's: compare by name).
        """
        if loop is None:
            return None
        tests = loop.final_tests
        return cls(
            model=model,
            alpha=loop.alpha,
            added=tuple(s.test.effect.label() for s in loop.steps),
            steps=tuple(
                AddedEffect(
                    name=s.test.effect.name,
                    statistic=json_number(s.test.statistic),
                    dof=int(s.test.dof),
                    p_value=json_number(s.test.p_value),
                    p_corrected=json_number(s.test.p_corrected),
                    streams=s.test.streams,
                )
                for s in loop.steps
            ),
            tested=tuple(dict.fromkeys(t.effect.label() for t in tests if t.identifiable)),
            with_rests=tuple(
                dict.fromkeys(t.effect.label() for t in tests if t.streams == "spin+rests")
            ),
            not_identifiable=tuple(t.effect.label() for t in loop.not_identifiable),
            smallest_p_corrected=json_number(
                min((t.p_corrected for t in tests if t.identifiable), default=float("nan"))
            ),
        )

    def screen_block(self) -> dict:
        """``fit.effects_screen``: what the loop added and tested on the final model."""
        return {
            "alpha": self.alpha,
            "correction": SCREEN_CORRECTION,
            "added": list(self.added),
            "tested": list(self.tested),
            "with_rests": list(self.with_rests),
            "smallest_p_corrected": self.smallest_p_corrected,
            "not_identifiable": list(self.not_identifiable),
        }

    def evidence_block(self, step: AddedEffect) -> dict:
        """``effects.<name>.evidence``: the score test that added ``step``."""
        return {
            "statistic": step.statistic,
            "dof": step.dof,
            "p_value": step.p_value,
            "p_corrected": step.p_corrected,
            "alpha": self.alpha,
            "test": EVIDENCE_TEST,
            "streams": step.streams,
        }

    def write_into(self, document: dict) -> None:
        """Write ``fit.effects_screen`` and each added effect's ``evidence`` into ``document``."""
        document["fit"]["effects_screen"] = self.screen_block()
        effects = document.get("effects", {})
        for step in self.steps:
            effects[step.name]["evidence"] = self.evidence_block(step)

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

    The check comes back as the field fit's :class:`~wheelcal.estimate.field.LeanCheck`
    (its ``alternative`` is the type's); its per-parameter shifts are read-only.
    """
    lean = document.get("bench", {}).get("lean")
    if lean is None:
        return None
    # here, not at the top: the field fit's package pulls in scipy.signal, which a
    # batch's planner must not import before it knows a session is to be computed
    from wheelcal.estimate.field import LeanCheck

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
        else LeanCheck(
            statistic=_optional(check["statistic"]),
            dof=int(check["dof"]),
            p_value=_optional(check["p_value"]),
            shift_sigma=_optional_map(check["shift_sigma"]),
            shift_z=_optional_map(check["shift_z"]),
            spacing_s=float(check["knot_spacing_s"]),
        ),
    )


def lean_block(lean: LeanReport) -> dict:
    """``bench.lean``, JSON-safe: the camber's change, the part in the turns, the track, the check.

    The inverse of :func:`lean_from_document`; the session's document and a
    :class:`~wheelcal.calibration.document.Calibration`'s are written by it.
    """
    out: dict = {"change_deg": lean.change_deg}
    if lean.in_turns_deg is not None:
        out["in_turns_deg_per_mps2"] = lean.in_turns_deg_per_mps2
        out["in_turns_std_deg_per_mps2"] = lean.in_turns_std_deg_per_mps2
        out["in_turns_deg"] = lean.in_turns_deg
    if lean.track is not None:
        out["track"] = {
            "followed": lean.track.followed,
            "gyro_range_deg": lean.track.gyro_range_deg,
            "beyond_gyro_errors_deg": lean.track.beyond_gyro_errors_deg,
            "reason": lean.track.reason,
        }
    if lean.check is not None:
        out["check"] = lean.check.to_dict()
    return json_safe(out)


@dataclass(frozen=True)
class CalibrationFacts:
    """The source, bench and fit figures a calibration document states, parsed once.

    A session's document has them all; a sensor's pooled one has only the noise floor,
    the unexplained residual, the ids, the parameters and the effects (the others are
    None there, and :class:`~wheelcal.calibration.document.Calibration` refuses to read
    them).  Arrays are read-only, NaN where the document has null.
    """

    #: The recording (``source.file``).
    source_file: str | None
    #: The fitted free-spin window, s from the first sample (``source.window_s``).
    window_s: tuple[float, float] | None
    sensor_id: str
    #: A sensor's: its sessions' mounting ids, comma-joined.
    mounting_id: str
    #: Bench tilt α, degrees (``bench.tilt_deg``).
    tilt_deg: float | None
    #: Sensor distance from the axle, used or fitted (``bench.radius_m``).
    radius_m: float | None
    #: R, bench → sensor (``bench.misalignment_matrix``).
    misalignment_matrix: np.ndarray | None
    #: Residual RMS per axis, m/s² (``fit.residual_rms_mps2``).
    residual_rms_mps2: np.ndarray | None
    #: The noise floor (rests or residual spectrum), m/s² (``fit.noise_floor_mps2``).
    noise_floor_mps2: np.ndarray | None
    #: √(residual² − floor²) per axis, m/s² (``fit.unexplained_mps2``).
    unexplained_mps2: np.ndarray | None
    #: Every reported parameter: name → (value, std), NaN where null.
    parameters: Mapping[str, tuple[float, float]]
    #: The effects in the model: name → their settings (read-only).
    effects: Mapping[str, Mapping]

    @classmethod
    def from_document(cls, document: Mapping) -> CalibrationFacts:
        """Parse ``source``, ``bench``, ``fit``, ``parameters`` and ``effects``."""
        source = document.get("source", {})
        bench = document.get("bench", {})
        fit = document.get("fit", {})

        def array(mapping: Mapping, key: str) -> np.ndarray | None:
            return None if mapping.get(key) is None else frozen_array(mapping[key])

        def scalar(mapping: Mapping, key: str) -> float | None:
            if key not in mapping:
                return None
            return float("nan") if mapping[key] is None else float(mapping[key])

        matrix = None
        if bench.get("misalignment_matrix") is not None:
            matrix = np.array(bench["misalignment_matrix"], dtype=float)
            matrix.setflags(write=False)
        window = source.get("window_s")
        if "mounting_ids" in source:
            mounting = ", ".join(m for m in source["mounting_ids"] if m)
        else:
            mounting = str(source.get("mounting_id", ""))
        nan = float("nan")
        return cls(
            source_file=None if source.get("file") is None else str(source["file"]),
            window_s=None if window is None else (float(window[0]), float(window[1])),
            sensor_id=str(source.get("sensor_id", "")),
            mounting_id=mounting,
            tilt_deg=scalar(bench, "tilt_deg"),
            radius_m=scalar(bench, "radius_m"),
            misalignment_matrix=matrix,
            residual_rms_mps2=array(fit, "residual_rms_mps2"),
            noise_floor_mps2=array(fit, "noise_floor_mps2"),
            unexplained_mps2=array(fit, "unexplained_mps2"),
            parameters=MappingProxyType(
                {
                    name: (
                        nan if p["value"] is None else float(p["value"]),
                        nan if p["std"] is None else float(p["std"]),
                    )
                    for name, p in document.get("parameters", {}).items()
                }
            ),
            effects=MappingProxyType(
                {
                    name: MappingProxyType(dict(entry.get("settings", {})))
                    for name, entry in document.get("effects", {}).items()
                }
            ),
        )

    def write_into(self, document: dict) -> None:
        """Write the figures back where ``document`` states them (the inverse of parsing)."""
        bench, fit = document.get("bench", {}), document.get("fit", {})
        for mapping, key, value in (
            (bench, "tilt_deg", self.tilt_deg),
            (bench, "radius_m", self.radius_m),
        ):
            if key in mapping:
                mapping[key] = json_number(value)
        if self.misalignment_matrix is not None:
            bench["misalignment_matrix"] = [json_numbers(r) for r in self.misalignment_matrix]
        for key in ("residual_rms_mps2", "noise_floor_mps2", "unexplained_mps2"):
            if getattr(self, key) is not None:
                fit[key] = json_numbers(getattr(self, key))
        if self.window_s is not None:
            document["source"]["window_s"] = list(self.window_s)
        for name, (value, std) in self.parameters.items():
            entry = document["parameters"][name]
            entry["value"], entry["std"] = json_number(value), json_number(std)
