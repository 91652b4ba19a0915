"""What can be wrong with a recording, in words that name it.

:class:`RecordingError` (a ``ValueError``) is a recording that cannot be
calibrated; :class:`InputError` one whose file or samples cannot be used (the
readers' errors in :mod:`wheelcal.io.errors` derive from it); :class:`SampleError`
samples the checks refuse; :class:`CalibrationRefused` a calibration a gate refused.
Every message starts with the file it is about (CONTRACT: "Errors name the file and
what is wrong").
"""

from __future__ import annotations

import os


class RecordingError(ValueError):
    """A recording that cannot be calibrated, with the reason in words."""


class CalibrationRefused(RecordingError):
    """A calibration was computed but fails a plausibility gate, so it is not given out.

    ``gate`` names the check (e.g. ``"gain_range"``), ``reason`` says what was
    seen and ``fix`` the likely remedy; ``str()`` is the whole message, naming
    the file.
    """

    def __init__(self, source: str, gate: str, reason: str, fix: str = "") -> None:
        self.source = source
        self.gate = gate
        self.reason = reason
        self.fix = fix
        text = f"{source}: refused ({gate}): {reason}"
        super().__init__(text + (f" — {fix}" if fix else ""))


class InputError(RecordingError):
    """An input file that cannot be used, with the file and the reason in the message."""

    def __init__(self, path: str | os.PathLike, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")

    def __reduce__(self):
        # Survive pickling (errors cross process boundaries in parallel batches).
        return (type(self), (self.path, self.problem))


class SampleError(InputError):
    """The samples themselves cannot be calibrated (too short, too many bad values, …)."""
