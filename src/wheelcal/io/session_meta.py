"""Session facts from the ``wheelcal.session`` metadata record, with overrides.

CONTRACT, input item 3: string values ``radius_m`` (needed, unless given on
the command line), optional ``radius_std_m``, ``sensor_id``, ``mounting_id``,
``gravity_mps2``, ``full_scale_g``, ``gyro_full_scale_dps`` (the gyroscope's
range, ±°/s), and free-form others (kept in
:attr:`SessionInfo.extra`).  Command-line values override the file.  Several
``wheelcal.session`` records are merged in file order (later keys win), so a
tool that appends a corrected record to a copy is honoured.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np

from wheelcal.io.errors import MetadataError
from wheelcal.recording import Recording, RecordingError, SessionInfo

SESSION_METADATA_NAME = "wheelcal.session"
FLOAT_KEYS = ("radius_m", "radius_std_m", "gravity_mps2", "full_scale_g", "gyro_full_scale_dps")
TEXT_KEYS = ("sensor_id", "mounting_id")
KNOWN_KEYS = FLOAT_KEYS + TEXT_KEYS


def _number(path: str, key: str, value: object, origin: str) -> float:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise MetadataError(path, f"{key} = {value!r} ({origin}) is not a number") from None
    if not np.isfinite(number):
        raise MetadataError(path, f"{key} = {value!r} ({origin}) is not a finite number")
    return number


def session_info(
    path: str | os.PathLike,
    records: list[Mapping[str, str]],
    overrides: Mapping[str, object] | None = None,
    defaults: Mapping[str, object] | None = None,
    gravity_forced: bool = False,
) -> SessionInfo:
    """Build :class:`SessionInfo` from ``wheelcal.session`` records and overrides.

    Parameters
    ----------
    path:
        The file, for error messages.
    records:
        The key-value maps of every ``wheelcal.session`` record, in file order.
    overrides:
        Values that replace the file's (e.g. from the command line), keyed by
        the names in :data:`KNOWN_KEYS`; ``None`` values are ignored.  An
        unknown key is an error (a typo must not be silently ignored).
    defaults:
        Values used where neither the file nor an override gives one (e.g. a
        pipeline file's defaults, CONTRACT input item 3); same keys.
    gravity_forced:
        Accept a gravity outside Earth's 9.7–9.9 m/s² (``--force-gravity``).

    Raises
    ------
    MetadataError
        Unknown override, unparsable number, non-positive radius, a gravity
        that is not Earth's, a non-positive full scale.
    """
    name = str(path)
    for given, what in ((overrides, "override"), (defaults, "default")):
        unknown = sorted(set(given or {}) - set(KNOWN_KEYS))
        if unknown:
            raise MetadataError(
                name, f"unknown session {what}(s) {unknown}; known: {list(KNOWN_KEYS)}"
            )
    merged: dict[str, tuple[object, str]] = {
        key: (value, "given as a default")
        for key, value in (defaults or {}).items()
        if value is not None
    }
    for record in records:
        merged.update(
            {key: (value, "in the file's wheelcal.session") for key, value in record.items()}
        )
    for key, value in (overrides or {}).items():
        if value is not None:
            merged[key] = (value, "given as an override")

    values: dict[str, object] = {}
    extra: list[tuple[str, str]] = []
    for key, (value, origin) in merged.items():
        if key in FLOAT_KEYS:
            values[key] = _number(name, key, value, origin)
        elif key in TEXT_KEYS:
            values[key] = str(value)
        else:
            extra.append((key, str(value)))
    radius = values.get("radius_m")
    if radius is not None and radius <= 0:  # type: ignore[operator]
        raise MetadataError(
            name,
            f"radius_m = {radius} ({merged['radius_m'][1]}) must be a positive length in metres",
        )
    for key in ("full_scale_g", "gyro_full_scale_dps"):
        full_scale = values.get(key)
        if full_scale is not None and full_scale <= 0:  # type: ignore[operator]
            raise MetadataError(name, f"{key} = {full_scale} must be positive")
    try:
        return SessionInfo(
            **values,  # type: ignore[arg-type]
            extra=tuple(sorted(extra)),
            gravity_forced=gravity_forced,
        )
    except RecordingError as exc:
        raise MetadataError(name, f"wheelcal.session: {exc}") from None


def require_radius(recording: Recording) -> float:
    """The wheel radius in metres, or a clear error naming the file.

    The reader accepts recordings without a radius (it may come from the
    command line or a pipeline file later); the estimator needs one.

    Raises
    ------
    MetadataError
        If neither the file nor an override gave ``radius_m``.
    """
    radius = recording.info.radius_m
    if radius is None:
        raise MetadataError(
            recording.source,
            "no wheel radius: the file's wheelcal.session metadata has no radius_m; "
            "give it on the command line (--radius M) or in the pipeline file",
        )
    return float(radius)
