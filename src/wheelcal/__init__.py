"""wheelcal — calibrate triaxial accelerometers with a spinning, tilted bicycle wheel.

Layers, lowest first.  A module imports only from its own package and from
lower layers (lazy imports included); packages on one line are siblings and do
not import each other.  Another package's modules are reached through its front
(its ``__init__``), and each entry's docstring states its number on a line
"Layer N (…)" (``tests/test_layers.py`` holds the code to this list):

    1. model, runtime        the physics (pure numpy); process settings
    2. recording             a recording, checked at construction; its errors
    3. io, simulate, estimate   files in and out; the simulator; the estimators
    4. closedloop            the effects the paper's model lacks, found and added
    5. session               one recording → one calibration: window, fit, loop, gates
    6. calibration           the documents (JSON), export, apply
    7. viz, plan             Rerun recordings; planning a bench
    8. study, batch          Monte Carlo studies; many sessions
    9. api, cli              the Python API; the command line

The root package only holds ``__version__`` (which any layer may import) and the
lazy names below.

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
