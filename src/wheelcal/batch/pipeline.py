"""Pipeline files (TOML) for ``wheelcal batch``: what to read, how, where to write, how to run.

Example (``pipelines/table2-repeatability.toml``)::

    [pipeline]
    name = "table2-repeatability"
    output = "out/table2-repeatability"     # relative to the current directory

    [inputs]
    globs = ["recordings/*.mcap"]           # optional when [simulate] makes them

    [simulate]                              # optional: generate the recordings first
    preset = "table2"
    count = 10
    seed = 2024

    [defaults]                              # used where neither the file nor the CLI gives a value
    radius_m = 0.28

    [run]
    calibrate = true
    rerun = true

    [executor]
    kind = "processes"                      # or "dask" (with address = "tcp://…")
    workers = 2

    [gates]                                 # optional: plausibility gates (README)
    gain_tolerance = 0.03                   # e.g. the MPU-9250's ±3 % sensitivity

Every key is checked: a typo is an error naming the file and the key, never silently ignored.
"""

from __future__ import annotations

import dataclasses
import glob
import math
import os
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from wheelcal.recording import SESSION_FACT_KEYS
from wheelcal.session import SESSION_GEOMETRIES, Gates, SessionOptions


class PipelineError(ValueError):
    """A pipeline file that cannot be used (names the file and the problem)."""


@dataclass(frozen=True)
class _Key:
    """What one key accepts: a TOML type, an optional range, and the words for both."""

    kind: str  # "str", "bool", "int", "number", "globs", "pair"
    allowed: str  # what the error message says is allowed
    within: Callable[[object], bool] | None = None


def _text(allowed: str = "a non-empty string") -> _Key:
    return _Key("str", allowed, lambda v: v != "")


def _choice(*options: str) -> _Key:
    return _Key("str", "one of " + ", ".join(repr(o) for o in options), lambda v: v in options)


def _positive(unit: str = "") -> _Key:
    return _Key("number", f"a number > 0{unit}", lambda v: v > 0)


_BOOL = _Key("bool", "true or false")
_GATE_KEYS = {
    f.name: _positive() for f in dataclasses.fields(Gates) if f.name not in ("gain_range",)
}
_GATE_KEYS["gain_range"] = _Key("pair", "[low, high] with 0 < low < 1 < high")
_GATE_KEYS["unexplained_ratio"] = _Key("number", "a number > 1", lambda v: v > 1)
_GATE_KEYS["rest_alpha"] = _Key("number", "a number in (0, 1)", lambda v: 0 < v < 1)
_FACTS = {
    "radius_m": _positive(" (m)"),
    "radius_std_m": _Key("number", "a number >= 0 (m)", lambda v: v >= 0),
    "gravity_mps2": _positive(" (m/s²)"),
    "full_scale_g": _positive(" (g)"),
    "gyro_full_scale_dps": _positive(" (°/s)"),
    "sensor_id": _text(),
    "mounting_id": _text(),
}
assert set(_FACTS) == set(SESSION_FACT_KEYS)
#: Largest [simulate] count: a typo like 1e9 must not fill the disk.
MAX_SIMULATED = 10_000

#: Every key of every section, with its type and range (a typo or a wrong type is an error).
_SECTIONS: dict[str, dict[str, _Key]] = {
    "pipeline": {"name": _text(), "output": _text("a folder path (string)")},
    "inputs": {
        "globs": _Key("globs", "a glob pattern or a list of them (strings)"),
        "topic": _text("a topic name (string)"),
        "ids_from": _choice("stem"),
    },
    "simulate": {
        "preset": _choice("table1", "table2"),
        "count": _Key(
            "int", f"a whole number from 1 to {MAX_SIMULATED}", lambda v: 1 <= v <= MAX_SIMULATED
        ),
        "seed": _Key("int", "a whole number >= 0", lambda v: v >= 0),
        "noise_mps2": _positive(" (m/s²)"),
        "bandwidth_hz": _positive(" (Hz)"),
        "format": _choice("ros2", "json"),
        "folder": _text("a folder path (string)"),
        "sensor_id": _text(),
        "mounting_id": _text(),
        "quantise": _BOOL,
        "push_and_stop": _BOOL,
    },
    "defaults": _FACTS,
    "overrides": _FACTS,
    "run": {
        "calibrate": _BOOL,
        "diagnose": _BOOL,
        "closure": _BOOL,
        "alpha": _Key("number", "a number in (0, 1)", lambda v: 0 < v < 1),
        "rerun": _BOOL,
        "geometry": _choice(*SESSION_GEOMETRIES),
        "known_tilt_deg": _Key("number", "a number in [0, 90] (°)", lambda v: 0 <= v <= 90),
        "tilt_std_deg": _Key("number", "a number >= 0 (°)", lambda v: v >= 0),
        "gyro": _choice("auto", "on", "off"),
        "model": _choice("closed_loop", "paper"),
        "gyro_g_sensitivity_dps_per_g": _positive(" (°/s/g)"),
    },
    "executor": {
        "kind": _choice("processes", "dask"),
        "workers": _Key("int", "a whole number >= 1", lambda v: v >= 1),
        "address": _text("a scheduler address such as 'tcp://host:8786'"),
    },
    "gates": _GATE_KEYS,
}


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _type_ok(kind: str, value: object) -> bool:
    if kind == "str":
        return isinstance(value, str)
    if kind == "bool":
        return isinstance(value, bool)
    if kind == "int":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "number":
        return _is_number(value)
    if kind == "globs":
        return isinstance(value, str) or (
            isinstance(value, list) and all(isinstance(v, str) and v for v in value)
        )
    if kind == "pair":
        return isinstance(value, list) and len(value) == 2 and all(map(_is_number, value))
    raise AssertionError(kind)


def _check_value(path: str, section: str, key: str, value: object) -> None:
    """Refuse a value of the wrong type or out of range, naming the key and what is allowed."""
    spec = _SECTIONS[section][key]
    ok = _type_ok(spec.kind, value) and (spec.within is None or spec.within(value))
    if not ok:
        shown = _toml_repr(value)
        raise PipelineError(
            f"{path}: [{section}] {key} = {shown} is not allowed: use {spec.allowed}"
        )


def _toml_repr(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"' if len(value) <= 80 else f'"{value[:77]}..."'
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


@dataclass(frozen=True)
class SimulateInputs:
    """Recordings the pipeline generates before calibrating (a self-contained demo)."""

    preset: str = "table2"
    count: int = 10
    seed: int = 0
    noise_mps2: float | None = None
    bandwidth_hz: float | None = None
    format: str = "ros2"
    folder: str = "recordings"
    sensor_id: str = "sim-sensor"
    mounting_id: str = "sim-mounting"
    quantise: bool = False
    push_and_stop: bool = True


@dataclass(frozen=True)
class Executor:
    """Where sessions run: local processes, or a Dask cluster."""

    kind: str = "processes"
    workers: int | None = None
    address: str | None = None


@dataclass(frozen=True)
class Pipeline:
    """A parsed, validated pipeline file."""

    path: str
    name: str
    output: Path
    globs: tuple[str, ...] = ()
    simulate: SimulateInputs | None = None
    options: SessionOptions = field(default_factory=SessionOptions)
    calibrate: bool = True
    diagnose: bool = False
    closure: bool = False
    rerun: bool = False
    executor: Executor = field(default_factory=Executor)
    #: ``"stem"``: each recording's file name (without its suffix) is its ``sensor_id`` and
    #: ``mounting_id`` where the pipeline gives none (logs that store no ids: CSV exports).
    ids_from: str | None = None

    def options_for(self, path: str | os.PathLike) -> SessionOptions:
        """The session options of one recording (its ids from its name with ``ids_from``)."""
        if self.ids_from != "stem":
            return self.options
        stem = Path(path).stem
        return dataclasses.replace(
            self.options,
            sensor_id=self.options.sensor_id or stem,
            mounting_id=self.options.mounting_id or stem,
        )

    def input_files(self) -> list[Path]:
        """Recordings matched by the globs plus the simulated ones (sorted, de-duplicated).

        Two spellings of one file (``a/x.mcap``, ``./b/../a/x.mcap``) count once.
        Folders are left out; a FIFO or device is kept, for the batch to refuse
        by name (it must never be read: ``/dev/zero`` never ends).
        """
        found: set[Path] = set(self.simulated_paths())
        for pattern in self.globs:
            found.update(Path(p) for p in glob.glob(os.path.expanduser(pattern), recursive=True))
        unique: dict[Path, Path] = {}
        for p in sorted(p for p in found if p.exists() and not p.is_dir()):
            unique.setdefault(p.resolve(), p)
        return sorted(unique.values())

    def simulated_paths(self) -> list[Path]:
        """Where the [simulate] section puts its recordings."""
        if self.simulate is None:
            return []
        folder = self.output / self.simulate.folder
        return [folder / f"session{i + 1:03d}.mcap" for i in range(self.simulate.count)]


def _check_keys(path: str, section: str, table: dict) -> None:
    unknown = set(table) - set(_SECTIONS[section])
    if unknown:
        raise PipelineError(
            f"{path}: unknown key(s) {sorted(unknown)} in [{section}]; "
            f"allowed: {sorted(_SECTIONS[section])}"
        )


def load_pipeline(path: str | os.PathLike) -> Pipeline:
    """Read and validate a pipeline TOML file."""
    path = str(path)
    data = _read_toml(path)
    _check_tables(path, data)
    head = data.get("pipeline", {})
    name = str(head.get("name", Path(path).stem))
    output = Path(head.get("output", f"out/{name}"))
    globs = data.get("inputs", {}).get("globs", [])
    if isinstance(globs, str):
        globs = [globs]
    simulate = _simulate_inputs(path, data)
    if not globs and simulate is None:
        raise PipelineError(f"{path}: no inputs: give [inputs] globs or a [simulate] section")
    run = data.get("run", {})
    executor = _executor(path, data.get("executor", {}))
    return Pipeline(
        path=path,
        name=name,
        output=output,
        globs=tuple(globs),
        simulate=simulate,
        options=_session_options(path, data),
        calibrate=bool(run.get("calibrate", True)),
        diagnose=bool(run.get("diagnose", False)),
        closure=bool(run.get("closure", run.get("diagnose", False))),
        rerun=bool(run.get("rerun", False)),
        executor=executor,
        ids_from=data.get("inputs", {}).get("ids_from"),
    )


def _read_toml(path: str) -> dict:
    """The parsed file; a PipelineError naming it when it cannot be read or parsed.

    A FIFO or a device is refused unread, and a file larger than any pipeline
    (:data:`~wheelcal.io.input_file.MAX_SMALL_INPUT_BYTES`) before it is read.
    """
    from wheelcal.io import SpecialFileError, read_bounded
    from wheelcal.recording import InputError

    try:
        return tomllib.loads(read_bounded(path, "pipeline").decode("utf-8"))
    except SpecialFileError as exc:
        if exc.problem.startswith("is a folder"):
            raise PipelineError(f"{path}: is a folder; give a pipeline file (TOML)") from None
        raise PipelineError(str(exc)) from None
    except InputError as exc:
        raise PipelineError(str(exc)) from None
    except FileNotFoundError:
        raise PipelineError(f"{path}: no such pipeline file") from None
    except IsADirectoryError:
        raise PipelineError(f"{path}: is a folder; give a pipeline file (TOML)") from None
    except OSError as exc:
        raise PipelineError(
            f"{path}: cannot read the pipeline file ({exc.strerror or exc})"
        ) from None
    except UnicodeDecodeError as exc:
        raise PipelineError(f"{path}: not valid TOML (not UTF-8: {exc.reason})") from None
    except RecursionError:
        raise PipelineError(f"{path}: not valid TOML (nested too deeply)") from None
    except tomllib.TOMLDecodeError as exc:
        raise PipelineError(f"{path}: not valid TOML ({exc})") from None


def _check_tables(path: str, data: dict) -> None:
    """Refuse an unknown section, a section that is not a table, an unknown key or value."""
    unknown = set(data) - set(_SECTIONS)
    if unknown:
        raise PipelineError(
            f"{path}: unknown section(s) {sorted(unknown)}; allowed: {sorted(_SECTIONS)}"
        )
    for section, table in data.items():
        if not isinstance(table, dict):
            raise PipelineError(f"{path}: [{section}] must be a table")
        _check_keys(path, section, table)
        for key, value in table.items():
            _check_value(path, section, key, value)


def _simulate_inputs(path: str, data: dict) -> SimulateInputs | None:
    """The [simulate] section, if any."""
    if "simulate" not in data:
        return None
    try:
        simulate = SimulateInputs(**data["simulate"])
    except TypeError as exc:
        raise PipelineError(f"{path}: [simulate]: {exc}") from None
    if simulate.count < 1 or simulate.format not in ("ros2", "json"):
        raise PipelineError(f"{path}: [simulate] needs count >= 1 and format 'ros2' or 'json'")
    return simulate


def _executor(path: str, table: dict) -> Executor:
    """The [executor] section (local processes by default)."""
    executor = Executor(**table)
    if executor.kind not in ("processes", "dask"):
        raise PipelineError(
            f"{path}: [executor] kind must be 'processes' or 'dask', got {executor.kind!r}"
        )
    if executor.kind == "dask" and not executor.address:
        raise PipelineError(f"{path}: [executor] kind = 'dask' needs address = 'tcp://host:port'")
    if executor.workers is not None and executor.workers < 1:
        raise PipelineError(f"{path}: [executor] workers must be >= 1")
    return executor


def _session_options(path: str, data: dict) -> SessionOptions:
    """Every session's options: [inputs] topic, [run], [defaults], [overrides] and [gates]."""
    run = data.get("run", {})
    gates_table = dict(data.get("gates", {}))
    if "gain_range" in gates_table:
        gates_table["gain_range"] = tuple(gates_table["gain_range"])
    try:
        gates = Gates(**gates_table)
    except (TypeError, ValueError) as exc:
        raise PipelineError(f"{path}: [gates]: {exc}") from None
    try:
        return SessionOptions(
            topic=data.get("inputs", {}).get("topic"),
            geometry=run.get("geometry", "auto"),
            known_tilt_deg=run.get("known_tilt_deg"),
            tilt_std_deg=run.get("tilt_std_deg", 0.5),
            rrd=bool(run.get("rerun", False)),
            diagnose=bool(run.get("diagnose", False)),
            alpha=float(run.get("alpha", 0.01)),
            gyro=str(run.get("gyro", "auto")),
            model=str(run.get("model", "closed_loop")),
            gyro_g_sensitivity_dps_per_g=float(run.get("gyro_g_sensitivity_dps_per_g", 0.1)),
            defaults=tuple(sorted(data.get("defaults", {}).items())),
            gates=gates,
            **data.get("overrides", {}),
        )
    except (TypeError, ValueError) as exc:
        raise PipelineError(f"{path}: {exc}") from None
