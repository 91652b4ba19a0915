"""One fit over several recordings of the same sensor.

The sensor's parameters — offset, gain and its intrinsic effects (cross-axis
coupling, nonlinearity) — are shared by every recording; each recording keeps
its own bench (tilt, mounting R), spin and local effects (warm-up, drift,
imbalance).  Each recording is whitened with its own noise model; their normal
equations are scattered into one system and solved by the same
Levenberg–Marquardt iteration as a single fit.

**Several mountings.**  One mounting sees only two columns of ΓR (the third
multiplies the constant g cosα and merges with the offset), so it cannot
separate cross-axis coupling from offsets and gains.  Mountings that put
different sensor directions along the wheel axis remove that: the joint fit
then identifies the full 9-parameter sensor model (3 offsets, 3 gains, 3
non-orthogonality angles).  When the mountings given are not different enough,
the shared block's Fisher information is (nearly) singular and the fit says so
instead of printing a confident number.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wheelcal.closedloop.score import IDENTIFIABLE_FRACTION
from wheelcal.estimate.joint import (
    CalibrationResult,
    NormalEquations,
    accumulate,
    block_information_fraction,
    covariance_from_fisher,
    levenberg_marquardt,
)
from wheelcal.model import (
    GAIN_NAMES,
    OFFSET_NAMES,
    CalibrationParams,
    Effect,
    ParameterLayout,
    SensorParams,
)
from wheelcal.recording import Recording


class _SharedLayout:
    """pack/unpack between a tuple of per-recording parameters and one global vector."""

    def __init__(self, layouts: Sequence[ParameterLayout], shared: Sequence[str]) -> None:
        self.layouts = tuple(layouts)
        self.shared = tuple(shared)
        self.maps = []
        names = list(self.shared)
        for k, layout in enumerate(self.layouts):
            index = np.empty(layout.size, dtype=int)
            for i, name in enumerate(layout.names):
                if name in self.shared:
                    index[i] = self.shared.index(name)
                else:
                    index[i] = len(names)
                    names.append(f"{name}@{k}")
            self.maps.append(index)
        self.names = tuple(names)
        self.size = len(names)

    def pack(self, state: tuple[CalibrationParams, ...]) -> np.ndarray:
        x = np.zeros(self.size)
        for layout, index, params in zip(self.layouts, self.maps, state, strict=True):
            x[index] = layout.pack(params)
        return x

    def unpack(self, x: np.ndarray, reference: tuple[CalibrationParams, ...]) -> tuple:
        return tuple(
            layout.unpack(x[index], ref)
            for layout, index, ref in zip(self.layouts, self.maps, reference, strict=True)
        )


@dataclass(frozen=True, eq=False)
class SensorFitResult:
    """The sensor's shared parameters with σ, and each recording's own fit."""

    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    recordings: tuple[CalibrationParams, ...]
    residual_rms_mps2: tuple[np.ndarray, ...]
    information_fraction: dict[str, float]
    best_single_std: dict[str, float]
    warnings: tuple[str, ...]
    iterations: int
    converged: bool

    def value_of(self, name: str) -> float:
        """Value of a shared parameter."""
        return float(self.values[self.names.index(name)])

    def std_of(self, name: str) -> float:
        """σ of a shared parameter."""
        return float(self.std[self.names.index(name)])

    def pooling_gain(self) -> dict[str, float]:
        """Best single recording's σ / pooled σ, per shared parameter."""
        return {
            n: self.best_single_std[n] / s
            for n, s in zip(self.names, self.std, strict=True)
            if n in self.best_single_std and s > 0 and np.isfinite(s)
        }

    def as_dict(self) -> dict:
        """JSON-ready summary."""

        def num(x):
            return float(x) if np.isfinite(x) else None

        return {
            "parameters": {
                n: {"value": num(v), "std": num(s)}
                for n, v, s in zip(self.names, self.values, self.std, strict=True)
            },
            "recordings": len(self.recordings),
            "residual_rms_mps2": [list(map(float, r)) for r in self.residual_rms_mps2],
            "information_fraction": {k: num(v) for k, v in self.information_fraction.items()},
            "best_single_std": {k: num(v) for k, v in self.best_single_std.items()},
            "pooling_gain": {k: num(v) for k, v in self.pooling_gain().items()},
            "warnings": list(self.warnings),
            "iterations": self.iterations,
            "converged": self.converged,
        }


@dataclass(frozen=True)
class SensorFit:
    """Joint fit over recordings of one sensor (see the module docstring).

    Parameters
    ----------
    shared_effects:
        Sensor-intrinsic effects fitted as shared parameters (e.g. ``CrossAxis()``).
    max_iterations:
        Levenberg–Marquardt iterations.
    """

    shared_effects: tuple[Effect, ...] = ()
    max_iterations: int = 60

    def fit(
        self, recordings: Sequence[Recording], starts: Sequence[CalibrationResult]
    ) -> SensorFitResult:
        """Fit; ``starts`` are the recordings' own fits (they give the starting point).

        Shared effects the recordings cannot identify are left out (never fitted
        into noise) and reported with their information fraction.
        """
        if len(recordings) != len(starts) or len(recordings) < 2:
            raise ValueError("a sensor fit needs two or more recordings, each with its own fit")
        probe = self._fit(recordings, starts, probe_only=True)
        keep = tuple(
            e
            for e in self.shared_effects
            if probe.information_fraction[e.name] >= IDENTIFIABLE_FRACTION
        )
        if keep == tuple(self.shared_effects):
            return self._fit(recordings, starts)
        result = SensorFit(keep, self.max_iterations)._fit(recordings, starts)
        fractions = {**result.information_fraction}
        warnings = list(result.warnings)
        for effect in self.shared_effects:
            if effect in keep:
                continue
            frac = probe.information_fraction[effect.name]
            fractions[effect.name] = frac
            warnings.append(
                f"{effect.name}: the recordings given cannot identify it (information fraction "
                f"{frac:.1e}); for cross-axis terms the mountings must put different sensor "
                "axes along the wheel axis — left out of the sensor model"
            )
        return dataclasses.replace(result, information_fraction=fractions, warnings=tuple(warnings))

    def _fit(self, recordings, starts, probe_only: bool = False) -> SensorFitResult:
        shared_names = _shared_names(self.shared_effects)
        state, shared = _start(starts, self.shared_effects, shared_names)
        data = [
            (rec.time_s - start.centre_s, rec.accel_mps2, start.noise)
            for rec, start in zip(recordings, starts, strict=True)
        ]

        def normal(st, want_jacobian: bool) -> NormalEquations:
            return _joint_normal(st, data, shared, want_jacobian)

        if probe_only:  # the information at the start, for the identifiability check
            fisher = normal(state, True).hessian
            return _probe_result(_fractions(fisher, shared_names, self.shared_effects))
        out = levenberg_marquardt(normal, state, shared, self.max_iterations, tol=1e-4)
        final = out.params
        fisher = out.normal.hessian
        cov = covariance_from_fisher(fisher)
        n_shared = len(shared_names)
        cov_shared = cov[:n_shared, :n_shared]
        std = np.sqrt(np.diag(cov_shared))
        values = shared.pack(final)[:n_shared]
        warnings = []
        fractions = _fractions(fisher, shared_names, self.shared_effects)
        for effect in self.shared_effects:
            if fractions[effect.name] < IDENTIFIABLE_FRACTION:
                std[_block(shared_names, effect)] = np.inf
                warnings.append(
                    f"{effect.name}: the recordings given cannot identify it (information "
                    f"fraction {fractions[effect.name]:.1e}): for cross-axis terms, mount the "
                    "sensor so that different sensor axes lie along the wheel axis"
                )
        best = {}
        for name in shared_names:
            stds = [s.std_of(name) for s in starts if name in s.names]
            if stds:
                best[name] = float(min(stds))
        residual_rms = tuple(
            np.sqrt(np.mean((v - _predict(p, t, lay)) ** 2, axis=0))
            for (t, v, _), lay, p in zip(data, shared.layouts, final, strict=True)
        )
        if not out.converged:
            warnings.append(f"the sensor fit did not converge ({out.message})")
        return SensorFitResult(
            names=tuple(shared_names),
            values=values,
            std=std,
            covariance=cov_shared,
            recordings=final,
            residual_rms_mps2=residual_rms,
            information_fraction=fractions,
            best_single_std=best,
            warnings=tuple(warnings),
            iterations=out.iterations,
            converged=out.converged,
        )


def _shared_names(shared_effects: Sequence[Effect]) -> list[str]:
    """The shared parameters: gains, offsets, then each shared effect's."""
    names = [*GAIN_NAMES, *OFFSET_NAMES]
    for effect in shared_effects:
        names += [f"{effect.name}.{p}" for p in effect.param_names]
    return names


def _block(shared_names: list[str], effect: Effect) -> list[int]:
    """The indices of ``effect``'s parameters among the shared ones."""
    return [shared_names.index(f"{effect.name}.{p}") for p in effect.param_names]


def _fractions(
    fisher: np.ndarray, shared_names: list[str], shared_effects: Sequence[Effect]
) -> dict[str, float]:
    """Each shared effect's information fraction (identifiable at ≥ IDENTIFIABLE_FRACTION)."""
    return {
        e.name: block_information_fraction(fisher, _block(shared_names, e)) for e in shared_effects
    }


def _start(
    starts: Sequence[CalibrationResult],
    shared_effects: Sequence[Effect],
    shared_names: list[str],
) -> tuple[tuple[CalibrationParams, ...], _SharedLayout]:
    """The starting state and the global layout of the recordings' joint fit.

    Each recording keeps its own bench, spin and local effects; the shared offsets and
    gains start at the inverse-variance mean of the single fits', shared effects at 0.
    """
    shared_effect_names = {e.name for e in shared_effects}
    layouts, state = [], []
    offsets, gains, weights_o, weights_g = [], [], [], []
    for start in starts:
        local = tuple(e for e in start.layout.effects if e.name not in shared_effect_names)
        layouts.append(
            ParameterLayout(
                spin_degree=start.layout.spin_degree,
                fit_tilt=start.layout.fit_tilt,
                fit_radius=start.layout.fit_radius,
                effects=local + tuple(shared_effects),
            )
        )
        offsets.append(start.params.sensor.offset_mps2)
        gains.append(start.params.sensor.gain)
        weights_o.append(1 / np.array([start.std_of(n) for n in OFFSET_NAMES]) ** 2)
        weights_g.append(1 / np.array([start.std_of(n) for n in GAIN_NAMES]) ** 2)
    offset0 = np.average(offsets, axis=0, weights=np.nan_to_num(weights_o))
    gain0 = np.average(gains, axis=0, weights=np.nan_to_num(weights_g))
    for start in starts:
        effects = {k: v for k, v in start.params.effects.items() if k not in shared_effect_names}
        state.append(
            start.params.with_changes(sensor=SensorParams(offset0, gain0), effects=effects)
        )
    return tuple(state), _SharedLayout(layouts, shared_names)


def _joint_normal(states, data, shared: _SharedLayout, want_jacobian: bool) -> NormalEquations:
    """Σ over recordings of their whitened normal equations, scattered into the global vector."""
    cost, entries = 0.0, 0
    hess = np.zeros((shared.size, shared.size)) if want_jacobian else None
    grad = np.zeros(shared.size) if want_jacobian else None
    for (t, v, noise), layout, index, params in zip(
        data, shared.layouts, shared.maps, states, strict=True
    ):
        part = accumulate(params, t, v, layout, noise, jacobian=want_jacobian)
        cost += part.cost
        entries += part.entries
        if want_jacobian:
            hess[np.ix_(index, index)] += part.hessian
            grad[index] += part.gradient
    return NormalEquations(cost, hess, grad, entries)


def sensor_crlb(
    states: Sequence[CalibrationParams],
    times_s: Sequence[np.ndarray],
    noises: Sequence,
    shared_effects: tuple[Effect, ...] = (),
) -> dict[str, float]:
    """Cramér–Rao bound of the shared sensor parameters for several recordings at ``states``.

    ``times_s`` are each recording's centred times; the states must share their
    sensor parameters (as a truth does).  Local effects in ``states`` are ignored.
    """
    shared_names = _shared_names(shared_effects)
    layouts = [
        ParameterLayout(spin_degree=s.spin.degree, effects=tuple(shared_effects)) for s in states
    ]
    shared = _SharedLayout(layouts, shared_names)
    data = [(t, np.zeros((t.size, 3)), n) for t, n in zip(times_s, noises, strict=True)]
    fisher = _joint_normal(tuple(states), data, shared, True).hessian
    cov = covariance_from_fisher(fisher)
    return dict(zip(shared_names, np.sqrt(np.diag(cov))[: len(shared_names)], strict=True))


def _probe_result(fractions: dict[str, float]) -> SensorFitResult:
    empty = np.zeros(0)
    return SensorFitResult((), empty, empty, np.zeros((0, 0)), (), (), fractions, {}, (), 0, False)


def _predict(params, t, layout):
    from wheelcal.model import predict

    return predict(params, t, layout)
