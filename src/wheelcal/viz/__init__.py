"""Rerun (``.rrd``) views of calibrations.

Layer 7 (above ``calibration``, beside ``plan``, below ``batch`` and ``study``).

* :mod:`wheelcal.viz.session_rrd` — one file per session: data and model with
  the free-spin window, residuals against time and per 5° of the wheel angle ϑ
  (with the ±2σ of noise, :mod:`~wheelcal.viz.angle_profile`), ω(t) of the
  model and as measured (:mod:`~wheelcal.viz.measured_rate`), a parameter
  report, and the closed loop's before/after; the layout is
  :mod:`~wheelcal.viz.session_blueprint`.
  :func:`~wheelcal.viz.session_rrd.session_rrd` lets a caller add residual
  sets and views before the file is written.
* :mod:`wheelcal.viz.batch_rrd` — one file per batch: every parameter per
  session with its predicted ±σ band, grouped by sensor and mounting, the
  spin's parameters apart (they differ per session by nature).

Files are written atomically (a reader never sees a partial ``.rrd``), each
from its own :class:`rerun.RecordingStream`: no global Rerun state.  The
submodules import ``rerun`` (heavy); this package does not, so importing
``wheelcal.viz`` costs nothing: its front's names (``_LAZY`` below) import their
module on first use (PEP 562).  The Rerun API moves between versions; this
code is written against the pinned ``rerun-sdk==0.41.0``.
"""

#: The front: name → the module that defines it, imported on first use.
_LAZY = {
    "OVERVIEW_FILE": "wheelcal.viz.batch_png",
    "overview_png": "wheelcal.viz.batch_png",
    "rrd_file": "wheelcal.viz.rrd_writer",
    "write_batch_rrd": "wheelcal.viz.batch_rrd",
    "write_session_rrd": "wheelcal.viz.session_rrd",
}

__all__ = [*_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'wheelcal.viz' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
