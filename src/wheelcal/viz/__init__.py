"""Rerun (``.rrd``) views of calibrations — the top layer, nothing below imports it.

* :mod:`wheelcal.viz.session_rrd` — one file per session: raw signal with the
  free-spin window, model fit, residuals against time and against the wheel
  angle ϑ, ω(t), a parameter report and a blueprint that lays them out.
  :func:`~wheelcal.viz.session_rrd.session_rrd` lets a caller (the closed loop)
  add more residual sets (``before``/``after``) before the file is written.
* :mod:`wheelcal.viz.batch_rrd` — one file per batch: every parameter per
  session with its predicted ±σ band, grouped by sensor and mounting.

Files are written atomically (a reader never sees a partial ``.rrd``), each
from its own :class:`rerun.RecordingStream`: no global Rerun state.  The
submodules import ``rerun`` (heavy); this package does not, so importing
``wheelcal.viz`` costs nothing.  The Rerun API moves between versions; this
code is written against the pinned ``rerun-sdk==0.41.0``.
"""
