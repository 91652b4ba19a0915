"""wheelcal — calibrate triaxial accelerometers with a spinning, tilted bicycle wheel.

Layers, one direction (each imports only from those above it):

``model`` (pure numpy) ← ``simulate`` / ``estimate`` ← ``diagnose`` ←
``io`` (MCAP), ``viz`` (Rerun), ``batch``, ``cli``; the Python API
(:mod:`wheelcal.api`, :mod:`wheelcal.calibration`) sits on top.

The API, imported lazily so that ``import wheelcal`` stays light::

    wheelcal.calibrate(path_or_recording, radius_m=..., **options) -> Calibration
    wheelcal.diagnose(path_or_recording, radius_m=..., **options) -> Calibration
    wheelcal.read_recording(path) -> Recording
    wheelcal.Calibration.from_json(path)
    wheelcal.CalibrationRefused, wheelcal.Gates, wheelcal.Recording
"""

__version__ = "0.1.0"

_LAZY = {
    "calibrate": ("wheelcal.api", "calibrate"),
    "diagnose": ("wheelcal.api", "diagnose"),
    "read_recording": ("wheelcal.api", "read_recording"),
    "Calibration": ("wheelcal.calibration.document", "Calibration"),
    "CalibrationRefused": ("wheelcal.recording", "CalibrationRefused"),
    "RecordingError": ("wheelcal.recording", "RecordingError"),
    "Recording": ("wheelcal.recording", "Recording"),
    "SessionInfo": ("wheelcal.recording", "SessionInfo"),
    "Gates": ("wheelcal.session.gates", "Gates"),
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        module, attribute = _LAZY[name]
        return getattr(importlib.import_module(module), attribute)
    raise AttributeError(f"module 'wheelcal' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
