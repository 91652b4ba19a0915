"""Settings of the accuracy study (``wheelcal study``), from a TOML file or defaults.

The defaults are the full study of the paper's Sec. IV-A: Table I truth,
σ_n log-spaced over 0.01–1 m/s² plus the two Table I levels, 60 noise
realisations per level for both estimators.  A TOML file has the tables
``[study]``, ``[noise_sweep]``, ``[static]`` and ``[duration]`` with the field
names below; an unknown table or key is an error (a typo must not be ignored).
"""

from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

#: Estimators the study knows, by the name used in its outputs.
ESTIMATORS = ("paper", "joint")


class StudyConfigError(ValueError):
    """An invalid study setting (names the key and what is wrong)."""


def _positive(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0):
        raise StudyConfigError(f"{name} must be positive, got {value!r}")


@dataclass(frozen=True)
class NoiseSweepConfig:
    """Monte Carlo over noise levels (paper Fig. 7–8, Table I).

    Parameters
    ----------
    sigma_min_mps2, sigma_max_mps2, levels:
        ``levels`` σ_n log-spaced from min to max (the paper: 0.01–1 m/s²).
    table_levels_mps2:
        Levels always included, for the Table I comparison (0.08 and 0.2 m/s²).
    realisations:
        Noise realisations per level for the joint fit (the paper: 60).
    paper_realisations:
        The same for the paper's estimator (~1 s per fit); ``None`` = ``realisations``.
        The paper method's runs reuse the joint fit's first seeds (paired comparison).
    """

    sigma_min_mps2: float = 0.01
    sigma_max_mps2: float = 1.0
    levels: int = 10
    table_levels_mps2: tuple[float, ...] = (0.08, 0.2)
    realisations: int = 60
    paper_realisations: int | None = None

    def __post_init__(self) -> None:
        _positive("noise_sweep.sigma_min_mps2", self.sigma_min_mps2)
        _positive("noise_sweep.sigma_max_mps2", self.sigma_max_mps2)
        if self.sigma_max_mps2 < self.sigma_min_mps2:
            raise StudyConfigError("noise_sweep.sigma_max_mps2 must be >= sigma_min_mps2")
        if self.levels < 0:
            raise StudyConfigError("noise_sweep.levels must be >= 0")
        object.__setattr__(
            self, "table_levels_mps2", tuple(float(s) for s in self.table_levels_mps2)
        )
        for s in self.table_levels_mps2:
            _positive("noise_sweep.table_levels_mps2", s)
        if not self.sigma_levels_mps2():
            raise StudyConfigError("noise_sweep has no noise level (levels = 0, no table levels)")
        if self.realisations < 2:
            raise StudyConfigError("noise_sweep.realisations must be >= 2 (a spread needs two)")
        if self.paper_realisations is not None and not (
            self.paper_realisations == 0 or 2 <= self.paper_realisations <= self.realisations
        ):
            raise StudyConfigError(
                "noise_sweep.paper_realisations must be 0 (skip the paper's method) "
                "or between 2 and realisations"
            )

    def sigma_levels_mps2(self) -> tuple[float, ...]:
        """The log-spaced levels and the Table I levels, sorted, without duplicates."""
        if self.levels == 1:
            swept = [self.sigma_min_mps2]
        else:
            swept = list(np.geomspace(self.sigma_min_mps2, self.sigma_max_mps2, self.levels))
        merged = sorted({round(float(s), 12) for s in [*swept, *self.table_levels_mps2]})
        return tuple(merged)

    def realisations_of(self, estimator: str) -> int:
        """Noise realisations per level for ``estimator`` (``"paper"`` or ``"joint"``)."""
        if estimator == "paper" and self.paper_realisations is not None:
            return self.paper_realisations
        return self.realisations


@dataclass(frozen=True)
class StaticConfig:
    """The six-pose static calibration users would pick instead (same sensor and noise).

    Parameters
    ----------
    poses:
        Number of still poses (6: each sensor axis up and down).
    settle_s:
        Time per pose that yields no usable data: turning the sensor to its next
        face and waiting for the hand-induced vibration to die out.  The poses
        share the *total* recording time of the wheel, so each keeps
        T/poses − settle_s of data.
    pose_error_deg:
        RMS deviation of each pose from its nominal axis (a hand-held box is not
        perfectly square to the table); the |a| = g fit does not need the poses.
    realisations:
        Monte Carlo runs (each fit takes microseconds).
    """

    poses: int = 6
    settle_s: float = 5.0
    pose_error_deg: float = 3.0
    realisations: int = 2000

    def __post_init__(self) -> None:
        if self.poses < 6:
            raise StudyConfigError("static.poses must be >= 6 (six unknowns)")
        if not (np.isfinite(self.settle_s) and self.settle_s >= 0):
            raise StudyConfigError("static.settle_s must be >= 0")
        if not (np.isfinite(self.pose_error_deg) and 0 <= self.pose_error_deg < 30):
            raise StudyConfigError("static.pose_error_deg must be in [0, 30)")
        if self.realisations < 2:
            raise StudyConfigError("static.realisations must be >= 2")


@dataclass(frozen=True)
class DurationConfig:
    """Precision against recording length and sampling rate (both methods).

    The wheel's curve is the CRLB of a physical spin (quadratic air drag from
    ``start_radps``, slowing to ``end_radps_at_90s`` after 90 s, as in Table I),
    checked by joint-fit Monte Carlo at the ``check_*`` points.

    Parameters
    ----------
    sigma_mps2:
        White noise σ_n of both methods.
    durations_s:
        Recording lengths (window for the wheel, total for the static poses).
    rates_hz:
        Sampling rates, at ``base_duration_s``.
    base_rate_hz, base_duration_s:
        The rate of the duration sweep and the length of the rate sweep.
    check_durations_s, check_rates_hz:
        Monte Carlo check points: each duration at ``base_rate_hz`` and each
        rate at ``base_duration_s``.
    check_realisations:
        Joint fits per check point (0 = no check).
    """

    sigma_mps2: float = 0.08
    durations_s: tuple[float, ...] = (30.0, 45.0, 60.0, 90.0, 120.0, 180.0, 240.0, 300.0)
    rates_hz: tuple[float, ...] = (50.0, 100.0, 200.0, 500.0, 1000.0)
    base_rate_hz: float = 200.0
    base_duration_s: float = 90.0
    start_radps: float = 9.0
    end_radps_at_90s: float = 6.4
    check_durations_s: tuple[float, ...] = (30.0, 300.0)
    check_rates_hz: tuple[float, ...] = (50.0, 1000.0)
    check_realisations: int = 30

    def __post_init__(self) -> None:
        _positive("duration.sigma_mps2", self.sigma_mps2)
        for name in ("durations_s", "rates_hz", "check_durations_s", "check_rates_hz"):
            values = tuple(float(v) for v in getattr(self, name))
            for v in values:
                _positive(f"duration.{name}", v)
            object.__setattr__(self, name, values)
        if not self.durations_s or not self.rates_hz:
            raise StudyConfigError("duration.durations_s and duration.rates_hz must not be empty")
        for name in ("base_rate_hz", "base_duration_s", "start_radps", "end_radps_at_90s"):
            _positive(f"duration.{name}", getattr(self, name))
        if self.end_radps_at_90s >= self.start_radps:
            raise StudyConfigError("duration.end_radps_at_90s must be below start_radps")
        if self.check_realisations != 0 and self.check_realisations < 2:
            raise StudyConfigError("duration.check_realisations must be 0 or >= 2")


@dataclass(frozen=True)
class StudyConfig:
    """Everything ``wheelcal study`` needs.

    Parameters
    ----------
    seed:
        Master seed; every realisation's seed derives from it (reproducible).
    workers:
        Worker processes; 0 = every core.
    noise_sweep, static, duration:
        The three parts of the study.
    """

    seed: int = 20240611
    workers: int = 0
    noise_sweep: NoiseSweepConfig = field(default_factory=NoiseSweepConfig)
    static: StaticConfig = field(default_factory=StaticConfig)
    duration: DurationConfig = field(default_factory=DurationConfig)

    def __post_init__(self) -> None:
        if self.workers < 0:
            raise StudyConfigError("study.workers must be >= 0")
        if self.seed < 0:
            raise StudyConfigError("study.seed must be >= 0")

    def to_dict(self) -> dict:
        """Plain dict (for the JSON output)."""
        return asdict(self)


_SECTIONS = {"noise_sweep": NoiseSweepConfig, "static": StaticConfig, "duration": DurationConfig}


def _build(cls, table: dict, where: str):
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(table) - known)
    if unknown:
        raise StudyConfigError(f"[{where}]: unknown key(s) {unknown}; known: {sorted(known)}")
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in table.items()}
    try:
        return cls(**values)
    except TypeError as exc:  # e.g. a string where a number belongs
        raise StudyConfigError(f"[{where}]: {exc}") from None


def config_from_dict(data: dict, source: str = "<dict>") -> StudyConfig:
    """Build a :class:`StudyConfig` from the TOML structure (module docstring)."""
    unknown = sorted(set(data) - {"study", *_SECTIONS})
    if unknown:
        raise StudyConfigError(
            f"{source}: unknown table(s) {unknown}; known: study, {', '.join(_SECTIONS)}"
        )
    try:
        sections = {
            name: _build(cls, dict(data.get(name, {})), name) for name, cls in _SECTIONS.items()
        }
        return _build(StudyConfig, {**dict(data.get("study", {})), **sections}, "study")
    except StudyConfigError as exc:
        raise StudyConfigError(f"{source}: {exc}") from None


def load_config(path: str | Path) -> StudyConfig:
    """Read a study TOML file (e.g. ``pipelines/table1-study.toml``)."""
    from wheelcal.io import read_bounded
    from wheelcal.recording import InputError

    path = Path(path)
    try:
        data = tomllib.loads(read_bounded(path, "study settings").decode("utf-8"))
    except InputError as exc:  # a FIFO, a device, a folder, a file of gigabytes
        raise StudyConfigError(str(exc)) from None
    except OSError as exc:
        raise StudyConfigError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise StudyConfigError(f"{path}: not valid TOML (not UTF-8: {exc.reason})") from None
    except RecursionError:
        raise StudyConfigError(f"{path}: not valid TOML (nested too deeply)") from None
    except tomllib.TOMLDecodeError as exc:
        raise StudyConfigError(f"{path}: not valid TOML: {exc}") from None
    return config_from_dict(data, str(path))


def with_overrides(config: StudyConfig, **changes) -> StudyConfig:
    """A copy with dotted-name overrides, e.g. ``{"noise_sweep.realisations": 8}``.

    ``None`` values are ignored (an option the user did not give).
    """
    grouped: dict[str, dict] = {}
    top: dict = {}
    for key, value in changes.items():
        if value is None:
            continue
        section, _, name = key.rpartition(".")
        if section:
            grouped.setdefault(section, {})[name] = value
        else:
            top[name] = value
    for section, values in grouped.items():
        top[section] = replace(getattr(config, section), **values)
    return replace(config, **top)
