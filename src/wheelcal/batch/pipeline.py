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
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from wheelcal.batch.session import SessionOptions
from wheelcal.estimate.gates import Gates
from wheelcal.recording import SESSION_FACT_KEYS


class PipelineError(ValueError):
    """A pipeline file that cannot be used (names the file and the problem)."""


_SECTIONS = {
    "pipeline": {"name", "output"},
    "inputs": {"globs", "topic"},
    "simulate": {
        "preset",
        "count",
        "seed",
        "noise_mps2",
        "bandwidth_hz",
        "format",
        "folder",
        "sensor_id",
        "mounting_id",
        "quantise",
        "push_and_stop",
    },
    "defaults": set(SESSION_FACT_KEYS),
    "overrides": set(SESSION_FACT_KEYS),
    "run": {
        "calibrate",
        "diagnose",
        "closure",
        "alpha",
        "rerun",
        "geometry",
        "known_tilt_deg",
        "tilt_std_deg",
        "gyro",
    },
    "executor": {"kind", "workers", "address"},
    "gates": {f.name for f in dataclasses.fields(Gates)},
}


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

    def input_files(self) -> list[Path]:
        """Recordings matched by the globs plus the simulated ones (sorted, de-duplicated).

        Two spellings of one file (``a/x.mcap``, ``./b/../a/x.mcap``) count once.
        """
        found: set[Path] = set(self.simulated_paths())
        for pattern in self.globs:
            found.update(Path(p) for p in glob.glob(os.path.expanduser(pattern), recursive=True))
        unique: dict[Path, Path] = {}
        for p in sorted(p for p in found if p.is_file()):
            unique.setdefault(p.resolve(), p)
        return sorted(unique.values())

    def simulated_paths(self) -> list[Path]:
        """Where the [simulate] section puts its recordings."""
        if self.simulate is None:
            return []
        folder = self.output / self.simulate.folder
        return [folder / f"session{i + 1:03d}.mcap" for i in range(self.simulate.count)]


def _check_keys(path: str, section: str, table: dict) -> None:
    unknown = set(table) - _SECTIONS[section]
    if unknown:
        raise PipelineError(
            f"{path}: unknown key(s) {sorted(unknown)} in [{section}]; "
            f"allowed: {sorted(_SECTIONS[section])}"
        )


def load_pipeline(path: str | os.PathLike) -> Pipeline:
    """Read and validate a pipeline TOML file."""
    path = str(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise PipelineError(f"{path}: no such pipeline file") from None
    except tomllib.TOMLDecodeError as exc:
        raise PipelineError(f"{path}: not valid TOML ({exc})") from None
    unknown = set(data) - set(_SECTIONS)
    if unknown:
        raise PipelineError(
            f"{path}: unknown section(s) {sorted(unknown)}; allowed: {sorted(_SECTIONS)}"
        )
    for section, table in data.items():
        if not isinstance(table, dict):
            raise PipelineError(f"{path}: [{section}] must be a table")
        _check_keys(path, section, table)
    head = data.get("pipeline", {})
    name = str(head.get("name", Path(path).stem))
    output = Path(head.get("output", f"out/{name}"))
    inputs = data.get("inputs", {})
    globs = inputs.get("globs", [])
    if isinstance(globs, str):
        globs = [globs]
    simulate = None
    if "simulate" in data:
        try:
            simulate = SimulateInputs(**data["simulate"])
        except TypeError as exc:
            raise PipelineError(f"{path}: [simulate]: {exc}") from None
        if simulate.count < 1 or simulate.format not in ("ros2", "json"):
            raise PipelineError(f"{path}: [simulate] needs count >= 1 and format 'ros2' or 'json'")
    if not globs and simulate is None:
        raise PipelineError(f"{path}: no inputs: give [inputs] globs or a [simulate] section")
    run = data.get("run", {})
    executor_table = data.get("executor", {})
    executor = Executor(**executor_table)
    if executor.kind not in ("processes", "dask"):
        raise PipelineError(
            f"{path}: [executor] kind must be 'processes' or 'dask', got {executor.kind!r}"
        )
    if executor.kind == "dask" and not executor.address:
        raise PipelineError(f"{path}: [executor] kind = 'dask' needs address = 'tcp://host:port'")
    if executor.workers is not None and executor.workers < 1:
        raise PipelineError(f"{path}: [executor] workers must be >= 1")
    overrides = data.get("overrides", {})
    gates_table = dict(data.get("gates", {}))
    if "gain_range" in gates_table:
        gates_table["gain_range"] = tuple(gates_table["gain_range"])
    try:
        gates = Gates(**gates_table)
    except (TypeError, ValueError) as exc:
        raise PipelineError(f"{path}: [gates]: {exc}") from None
    try:
        options = SessionOptions(
            topic=inputs.get("topic"),
            geometry=run.get("geometry", "radius"),
            known_tilt_deg=run.get("known_tilt_deg"),
            tilt_std_deg=run.get("tilt_std_deg", 0.5),
            rrd=bool(run.get("rerun", False)),
            diagnose=bool(run.get("diagnose", False)),
            alpha=float(run.get("alpha", 0.01)),
            gyro=str(run.get("gyro", "auto")),
            defaults=tuple(sorted(data.get("defaults", {}).items())),
            gates=gates,
            **overrides,
        )
    except (TypeError, ValueError) as exc:
        raise PipelineError(f"{path}: {exc}") from None
    return Pipeline(
        path=path,
        name=name,
        output=output,
        globs=tuple(globs),
        simulate=simulate,
        options=options,
        calibrate=bool(run.get("calibrate", True)),
        diagnose=bool(run.get("diagnose", False)),
        closure=bool(run.get("closure", run.get("diagnose", False))),
        rerun=bool(run.get("rerun", False)),
        executor=executor,
    )
