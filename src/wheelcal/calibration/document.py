"""The calibration of one session as a typed, immutable object.

:class:`Calibration` wraps the contract's calibration document
(``wheelcal.calibration/1``, see README "Outputs") with typed accessors, so
notebooks, tools and wheelcal's own reports read named values instead of
digging through dictionaries:

    cal = wheelcal.calibrate("spin.mcap", radius_m=0.28)
    cal.gain, cal.offset_mps2, cal.gain_std          # arrays, NaN where undetermined
    cal.apply(raw_samples)                           # a = M (v − b)
    cal.to_json("spin.calibration.json")
    Calibration.from_json("spin.calibration.json").summary()

One loader reads both kinds of calibration document: a session's
(``wheelcal.calibration/1``) and a sensor's pooled one
(``wheelcal.sensor_calibration/1``, the batch's ``sensors/<id>.calibration.json``)::

    cal = Calibration.from_json("out/sensors/mpu9250-A.calibration.json")
    cal.kind                                         # "sensor" (or "session")
    cal.gain, cal.correction, cal.apply(raw_samples), cal.summary()

The sensor, correction, σ, parameters and warnings read alike; what only a
session has (bench, window, residuals) raises a ``ValueError`` that says so.

It is one value from the fit to the file: built once from the document — the one
:func:`~wheelcal.calibration.session_json.calibration_dict` makes of the calibrated
session, or the one read back — its typed, frozen fields (the sensor's numbers,
``correction``, ``warnings``, ``undetermined``, the closed loop's ``diagnosis``
(:class:`~wheelcal.calibration.values.CalibrationDiagnosis`), a rolling wheel's
``lean`` (:class:`~wheelcal.session.LeanReport`), the source, bench and fit figures
(``facts``, :class:`~wheelcal.calibration.values.CalibrationFacts`, read by the
accessors)) are parsed at construction and read the same in the process that
computed it and in one that loaded it.  ``to_dict`` and ``to_json`` write the
document from those fields, by the same blocks the session's document is written
with (:mod:`.values`); the keys no field holds are written as the document has them.

A calibration computed in this process also carries the full
:class:`~wheelcal.estimate.joint.result.CalibrationResult` (residuals, noise model,
covariance) as ``result`` and the closed loop's whole report as ``closed_loop``;
one read from a file carries only the document.  Values the recording could not
determine are NaN here and ``null`` in the file, and are named in ``undetermined``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from wheelcal.calibration.values import (
    CalibrationDiagnosis,
    CalibrationFacts,
    lean_block,
    lean_from_document,
    sensor_fields,
    write_sensor_fields,
)
from wheelcal.estimate.joint import CalibrationResult
from wheelcal.model import AXES, SensorCorrection
from wheelcal.recording import Recording
from wheelcal.session import Assessment, LeanReport, SessionResult

if TYPE_CHECKING:
    from wheelcal.calibration.session_files import RrdWriter, WrittenFiles
    from wheelcal.session import SessionOptions


#: JSON's scalar types: a list of only these has nothing inside to freeze or thaw.
_SCALARS = frozenset({float, int, str, bool, type(None)})


def _frozen(value):
    """A read-only view of nested JSON data."""
    if isinstance(value, dict):
        return MappingProxyType(
            {k: v if type(v) in _SCALARS else _frozen(v) for k, v in value.items()}
        )
    if isinstance(value, list):
        if _SCALARS.issuperset(map(type, value)):  # numbers and strings (most lists)
            return tuple(value)
        return tuple(_frozen(v) for v in value)
    return value


def _thawed(value):
    if isinstance(value, Mapping):
        return {k: v if type(v) in _SCALARS else _thawed(v) for k, v in value.items()}
    if isinstance(value, tuple):
        if _SCALARS.issuperset(map(type, value)):
            return list(value)
        return [_thawed(v) for v in value]
    return value


def read_only_document(calibration: Mapping) -> Mapping:
    """The contract document to read from: a :class:`Calibration`'s own (no copy), else as given.

    A :class:`Calibration`'s item access returns a fresh deep copy each time
    (callers may change it); code that only reads many values uses this.
    """
    return calibration.document if isinstance(calibration, Calibration) else calibration


@dataclass(frozen=True, eq=False)
class Calibration(Mapping):
    """A calibration document — one session's or one sensor's pooled — typed.

    It is also a read-only mapping of the document's top-level keys (each
    value a fresh plain copy), so code written for the JSON reads it too.

    Parameters
    ----------
    document:
        The contract dictionary (``wheelcal.calibration/1`` or
        ``wheelcal.sensor_calibration/1``); kept read-only.
    session:
        The calibrated session (:class:`~wheelcal.session.result.SessionResult`:
        the fit, the gates' assessment, the closed loop's report) when it was
        computed in this process; None for one read from a file.

    The typed fields below are parsed from ``document`` once, at construction.
    """

    document: Mapping
    session: SessionResult | None = None
    #: ``"session"`` (one recording) or ``"sensor"`` (pooled from a batch's sessions).
    kind: str = field(init=False, repr=False)
    #: Gain γ per axis (NaN where undetermined).
    gain: np.ndarray = field(init=False, repr=False)
    #: Offset o per axis, m/s² (NaN where undetermined).
    offset_mps2: np.ndarray = field(init=False, repr=False)
    #: Statistical σ of the gains.
    gain_std: np.ndarray = field(init=False, repr=False)
    #: Statistical σ of the offsets, m/s².
    offset_std_mps2: np.ndarray = field(init=False, repr=False)
    #: Systematic σ of the gains (radius, gravity, clock): shared, never averaged away.
    systematic_gain_std: np.ndarray = field(init=False, repr=False)
    #: Systematic σ of the offsets, m/s².
    systematic_offset_std_mps2: np.ndarray = field(init=False, repr=False)
    #: (parameter, reason) for every value the recording could not determine.
    undetermined: tuple[tuple[str, str], ...] = field(init=False, repr=False)
    #: The correction a = M (v − b) (identity rows on undetermined axes).
    correction: SensorCorrection = field(init=False, repr=False)
    #: Every warning of the fit and the gates.
    warnings: tuple[str, ...] = field(init=False, repr=False)
    #: What the closed loop did (effects added with their evidence, the screen); None
    #: when the fit had no closed loop (``model="paper"``, a wheel in the field).
    diagnosis: CalibrationDiagnosis | None = field(init=False, repr=False)
    #: A rolling wheel's camber over the drive (``bench.lean``); None elsewhere.
    lean: LeanReport | None = field(init=False, repr=False)
    #: The source, bench and fit figures (read through the accessors below, which
    #: refuse a sensor's document what only a session has).
    facts: CalibrationFacts = field(init=False, repr=False)

    def __post_init__(self) -> None:
        from wheelcal.calibration.session_json import (
            CORRECTION_FORMATS,
            SENSOR_CALIBRATION_FORMAT,
            CalibrationFileError,
        )

        if self.document.get("format") not in CORRECTION_FORMATS:
            raise CalibrationFileError(
                f"not a {' or '.join(CORRECTION_FORMATS)} document "
                f"(format {self.document.get('format')!r})"
            )
        if not isinstance(self.document, MappingProxyType):
            object.__setattr__(self, "document", _frozen(dict(self.document)))
        document = self.document
        kind = "sensor" if document["format"] == SENSOR_CALIBRATION_FORMAT else "session"
        typed = {
            "kind": kind,
            **sensor_fields(document),
            "diagnosis": CalibrationDiagnosis.from_document(document),
            "lean": lean_from_document(document),
            "facts": CalibrationFacts.from_document(document),
        }
        for name, value in typed.items():
            object.__setattr__(self, name, value)

    # the document as a mapping -----------------------------------------------------
    def __getitem__(self, key: str):
        return _thawed(self.document[key])

    def __iter__(self):
        return iter(self.document)

    def __len__(self) -> int:
        return len(self.document)

    __hash__ = object.__hash__

    # construction -----------------------------------------------------------------
    @classmethod
    def from_session(cls, session: SessionResult, provenance: dict | None = None) -> Calibration:
        """The calibration of a calibrated session (:mod:`wheelcal.session.compute`)."""
        from wheelcal.calibration.session_json import calibration_dict

        return cls(calibration_dict(session, provenance), session=session)

    @classmethod
    def compute(
        cls,
        source: str | os.PathLike | Recording,
        options: SessionOptions,
        provenance: dict | None = None,
    ) -> Calibration:
        """Calibrate one recording (a path, or a :class:`~wheelcal.recording.Recording`).

        The one session function: ``wheelcal.calibrate()``, ``diagnose()``, the command
        line and the batch all compute a session here (no files are written;
        :meth:`write` writes them).  ``provenance`` is stored in the document (the
        batch's up-to-date check).  Raises as
        :func:`~wheelcal.session.compute.compute_session` does.
        """
        from wheelcal.session import compute_recording, compute_session

        if isinstance(source, Recording):
            info = source.info.merged(**options.info_overrides())
            checked = source.checked(unit=options.accel_unit, info=info)
            session = compute_recording(checked, options)
        else:
            session = compute_session(source, options)
        return cls.from_session(session, provenance)

    def write(
        self,
        folder: str | os.PathLike,
        stem: str | None = None,
        rrd_writer: RrdWriter | None = None,
        diagnosis: bool = False,
        durable: bool = True,
    ) -> WrittenFiles:
        """Write this session's files into ``folder``: the ``.rrd``, the report, the JSON.

        :func:`~wheelcal.calibration.session_files.write_session_files` (the one writer):
        ``stem`` names them (default: the recording's file name); ``rrd_writer``
        draws the ``.rrd`` (``wheelcal.viz.write_session_rrd``; None: none);
        ``diagnosis`` adds ``<stem>.diagnosis.json``.
        """
        from wheelcal.calibration.session_files import session_stem, write_session_files

        if self.session is None:
            raise ValueError("only a calibration computed in this process has a session's files")
        stem = stem or session_stem(self.session.source)
        document = self.to_dict()  # the JSON and the view's verdict
        return write_session_files(
            self.session, document, folder, stem, rrd_writer, diagnosis, durable
        )

    # the computation behind it (this process only) ---------------------------------
    @property
    def result(self) -> CalibrationResult | None:
        """The joint fit's result (residuals, noise model, covariance, χ²), if computed here."""
        return None if self.session is None else self.session.result

    @property
    def assessment(self) -> Assessment | None:
        """What the gates made of the fit (noise floor, checks, warnings), if computed here."""
        return None if self.session is None else self.session.assessment

    @property
    def closed_loop(self):
        """The closed loop's whole report, if computed here (else None).

        :class:`~wheelcal.closedloop.Diagnosis`: every step's fit and tests, the
        harmonics; :attr:`diagnosis` is what the document keeps of it.
        """
        return None if self.session is None else self.session.diagnosis

    @classmethod
    def from_json(cls, path: str | os.PathLike, allow_partial: bool = True) -> Calibration:
        """Read a calibration file (``allow_partial=False`` refuses undetermined parameters)."""
        from wheelcal.calibration.session_json import load_calibration

        return cls(load_calibration(path, allow_partial=allow_partial))

    @classmethod
    def from_document(
        cls, document: dict, path: str | os.PathLike, allow_partial: bool = True
    ) -> Calibration:
        """As :meth:`from_json`, for the document already read from ``path`` (same checks)."""
        from wheelcal.calibration.session_json import check_calibration

        return cls(check_calibration(document, path, allow_partial=allow_partial))

    def to_dict(self) -> dict:
        """The contract dictionary (a mutable copy), written from the typed fields.

        The sensor's numbers, the correction, the warnings, the closed loop's
        ``diagnosis``, the ``lean`` and the ``facts`` are written from their values
        (:mod:`.values`, the blocks the session's document was written by); the keys
        no field holds (covariance, noise model, gates, motion …) as the document
        has them, in the document's order.
        """
        document = _thawed(self.document)
        write_sensor_fields(document, self)
        self.facts.write_into(document)
        if self.diagnosis is not None:
            self.diagnosis.write_into(document)
        if self.lean is not None:
            document["bench"]["lean"] = lean_block(self.lean)
        return document

    def to_json(self, path: str | os.PathLike, durable: bool = True) -> Path:
        """Write the contract JSON atomically; returns the path."""
        from wheelcal.io import atomic_write_text

        text = json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n"
        atomic_write_text(path, text, durable=durable)
        return Path(path)

    # which document --------------------------------------------------------------
    def _session_only(self, what: str) -> None:
        if self.kind == "sensor":
            sessions = self.document.get("pooling", {}).get("sessions", "?")
            raise ValueError(
                f"{what}: a sensor's pooled calibration (from {sessions} sessions) has none; "
                "read a session's <stem>.calibration.json for it"
            )

    @property
    def origin(self) -> str:
        """Where it comes from: the recording, or the sensor and how many sessions."""
        from wheelcal.calibration.export import origin

        return origin(self.to_dict())

    # the sensor ---------------------------------------------------------------------
    def apply(self, samples_mps2: np.ndarray, allow_partial: bool = False) -> np.ndarray:
        """Corrected specific force (N, 3) from raw samples (N, 3) in m/s².

        Raises ``ValueError`` for a partial calibration unless ``allow_partial``
        (its undetermined axes would pass unchanged).
        """
        if self.undetermined and not allow_partial:
            names = ", ".join(name for name, _ in self.undetermined)
            raise ValueError(
                f"this calibration could not determine {names}: those axes would pass "
                "unchanged; use apply(..., allow_partial=True) to accept that"
            )
        return self.correction.apply(samples_mps2)

    # the bench, the fit, the source ------------------------------------------------
    def _fact(self, what: str):
        """A session's figure from :attr:`facts` (refused for a sensor's document)."""
        self._session_only(what)
        value = getattr(self.facts, what)
        if value is None:
            raise KeyError(f"{what}: not in this calibration document")
        return value

    @property
    def tilt_deg(self) -> float:
        """Bench tilt α."""
        return self._fact("tilt_deg")

    @property
    def radius_m(self) -> float:
        """Sensor distance from the axle used (or fitted)."""
        return self._fact("radius_m")

    @property
    def misalignment_matrix(self) -> np.ndarray:
        """R, bench → sensor (read-only)."""
        return self._fact("misalignment_matrix")

    @property
    def noise_floor_mps2(self) -> np.ndarray | None:
        """The sensor's noise floor (rests or residual spectrum), independent of the fit."""
        return self.facts.noise_floor_mps2

    @property
    def unexplained_mps2(self) -> np.ndarray | None:
        """√(residual² − floor²) per axis."""
        return self.facts.unexplained_mps2

    @property
    def residual_rms_mps2(self) -> np.ndarray:
        """Residual RMS per axis."""
        return self._fact("residual_rms_mps2")

    @property
    def source_file(self) -> str:
        """The recording this calibration came from."""
        return self._fact("source_file")

    @property
    def sensor_id(self) -> str:
        """The sensor's identifier (may be empty)."""
        return self.facts.sensor_id

    @property
    def mounting_id(self) -> str:
        """The mounting's identifier (may be empty; a sensor's: its sessions' ids, comma-joined)."""
        return self.facts.mounting_id

    @property
    def window_s(self) -> tuple[float, float]:
        """The fitted free-spin window, s from the first sample."""
        return self._fact("window_s")

    @property
    def parameters(self) -> dict[str, tuple[float, float]]:
        """Every reported parameter as (value, std), NaN where null (a fresh dict)."""
        return dict(self.facts.parameters)

    @property
    def effects(self) -> dict[str, dict]:
        """Effects in the model: name → settings (empty for the paper's model; fresh dicts)."""
        return {name: dict(settings) for name, settings in self.facts.effects.items()}

    def value(self, name: str) -> float:
        """Value of one reported parameter (NaN when undetermined)."""
        return self.parameters[name][0]

    def std(self, name: str) -> float:
        """σ of one reported parameter (NaN when undetermined)."""
        return self.parameters[name][1]

    def summary(self) -> str:
        """A few lines for people: sensor ± σ (systematic σ), bench, fit, warnings."""
        lines = [f"{self.origin}: wheelcal calibration ({self.document['format']})"]
        undetermined = {name for name, _ in self.undetermined}
        for i, axis in enumerate(AXES):
            parts = []
            gain_sys = self.systematic_gain_std[i]
            for name, value, std, sys, unit, digits in (
                (f"gain_{axis}", self.gain[i], self.gain_std[i], gain_sys, "", 5),
                (
                    f"offset_{axis}_mps2",
                    self.offset_mps2[i],
                    self.offset_std_mps2[i],
                    self.systematic_offset_std_mps2[i],
                    " m/s²",
                    4,
                ),
            ):
                if name in undetermined:
                    parts.append(f"{name.split('_')[0]} undetermined")
                else:
                    parts.append(
                        f"{name.split('_')[0]} {value:+.{digits}f} ± {std:.{digits}f} "
                        f"(sys {sys:.{digits}f}){unit}"
                    )
            lines.append(f"  {axis}: " + "   ".join(parts))
        if self.kind == "session":
            lines.append(f"  tilt {self.tilt_deg:.3f}°, radius {self.radius_m:.4g} m")
            floor = self.noise_floor_mps2
            rms = " ".join(f"{x:.4f}" for x in self.residual_rms_mps2)
            lines.append(
                f"  residual rms {rms} m/s²"
                + (
                    ""
                    if floor is None
                    else " vs noise floor " + " ".join(f"{x:.4f}" for x in floor)
                )
            )
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def __repr__(self) -> str:
        gains = ", ".join(f"{g:.5g}" for g in self.gain)
        offsets = ", ".join(f"{o:.4g}" for o in self.offset_mps2)
        return (
            f"Calibration({self.origin!r}, gain=[{gains}], offset_mps2=[{offsets}], "
            f"warnings={len(self.warnings)})"
        )
