"""The one mapping between named parameters and the optimiser's flat vector.

Every estimator, the Cramér–Rao bound and the diagnostics go through
:class:`ParameterLayout`; nothing else slices parameter vectors.

The misalignment enters the vector as a *local* rotation vector δ (rad) about
the current R, R(δ) = R·exp([δ]×): :meth:`ParameterLayout.pack` always writes
δ = 0 and :meth:`ParameterLayout.unpack` applies δ to the reference rotation.
This keeps R a proper rotation and avoids gimbal lock in the fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from wheelcal.model.parameters import (
    AXES,
    BenchParams,
    CalibrationParams,
    SensorParams,
    SpinParams,
    spin_coefficient_names,
)

ROTATION_NAMES = tuple(f"rotation_{a}_rad" for a in AXES)
GAIN_NAMES = tuple(f"gain_{a}" for a in AXES)
OFFSET_NAMES = tuple(f"offset_{a}_mps2" for a in AXES)


@dataclass(frozen=True)
class ParameterLayout:
    """Which parameters are free, and their order in the optimiser vector.

    Parameters
    ----------
    spin_degree:
        Degree K of the ω(t) polynomial (3 = the paper's cubic).
    fit_tilt, fit_radius:
        Geometry mode.  The paper fixes r (``fit_radius=False``); eq. (9)–(13)
        show that r and α cannot both be free — unless an effect ``ties_tilt``
        (measures α otherwise: a gyro angle that turns with a cambered wheel's yaw).
    effects:
        Optional model extensions, each with named parameters (see
        :mod:`wheelcal.model.effects`).
    """

    spin_degree: int = 3
    fit_tilt: bool = True
    fit_radius: bool = False
    effects: tuple = field(default=())

    def __post_init__(self) -> None:
        if (
            self.fit_tilt
            and self.fit_radius
            and not any(getattr(e, "ties_tilt", False) for e in self.effects)
        ):
            raise ValueError(
                "tilt and radius cannot both be free: eq. (9)-(13) null space (unless an "
                "effect measures the tilt otherwise, e.g. a cambered wheel's turns)"
            )
        if self.spin_degree < 0:
            raise ValueError("spin_degree must be >= 0")

    @cached_property
    def blocks(self) -> dict[str, slice]:
        """Name of each parameter block → its slice in the flat vector."""
        sizes = [("spin", self.spin_degree + 2)]
        if self.fit_tilt:
            sizes.append(("tilt", 1))
        if self.fit_radius:
            sizes.append(("radius", 1))
        sizes += [("rotation", 3), ("gain", 3), ("offset", 3)]
        sizes += [(f"effect:{e.name}", len(e.param_names)) for e in self.effects]
        out, start = {}, 0
        for name, size in sizes:
            out[name] = slice(start, start + size)
            start += size
        return out

    @cached_property
    def names(self) -> tuple[str, ...]:
        """Optimiser-vector names, in order."""
        names = ["theta0_rad", *spin_coefficient_names(self.spin_degree)]
        if self.fit_tilt:
            names.append("tilt_rad")
        if self.fit_radius:
            names.append("radius_m")
        names += [*ROTATION_NAMES, *GAIN_NAMES, *OFFSET_NAMES]
        for effect in self.effects:
            names += [f"{effect.name}.{p}" for p in effect.param_names]
        return tuple(names)

    @property
    def size(self) -> int:
        """Number of free parameters."""
        return len(self.names)

    def index(self, name: str) -> int:
        """Position of a named parameter in the flat vector."""
        return self.names.index(name)

    def pack(self, params: CalibrationParams) -> np.ndarray:
        """Flat vector of the free parameters (rotation entries are δ = 0)."""
        if params.spin.degree != self.spin_degree:
            raise ValueError(
                f"layout expects a degree-{self.spin_degree} spin, got {params.spin.degree}"
            )
        x = np.zeros(self.size)
        b = self.blocks
        x[b["spin"]] = [params.spin.theta0_rad, *params.spin.omega_radps]
        if self.fit_tilt:
            x[b["tilt"]] = params.bench.tilt_rad
        if self.fit_radius:
            x[b["radius"]] = params.bench.radius_m
        x[b["gain"]] = params.sensor.gain
        x[b["offset"]] = params.sensor.offset_mps2
        for effect in self.effects:
            x[b[f"effect:{effect.name}"]] = params.effect(effect.name, len(effect.param_names))
        return x

    def unpack(self, x: np.ndarray, reference: CalibrationParams) -> CalibrationParams:
        """Parameters from a flat vector; fixed ones and R's base come from ``reference``."""
        x = np.asarray(x, dtype=float)
        if x.shape != (self.size,):
            raise ValueError(f"expected {self.size} values, got shape {x.shape}")
        b = self.blocks
        spin_vec = x[b["spin"]]
        spin = SpinParams(theta0_rad=spin_vec[0], omega_radps=spin_vec[1:])
        bench = BenchParams(
            tilt_rad=x[b["tilt"]][0] if self.fit_tilt else reference.bench.tilt_rad,
            radius_m=x[b["radius"]][0] if self.fit_radius else reference.bench.radius_m,
            misalignment=reference.bench.misalignment.perturbed(x[b["rotation"]]),
        )
        sensor = SensorParams(offset_mps2=x[b["offset"]], gain=x[b["gain"]])
        effects = dict(reference.effects)
        for effect in self.effects:
            effects[effect.name] = x[b[f"effect:{effect.name}"]]
        return CalibrationParams(
            spin=spin,
            bench=bench,
            sensor=sensor,
            gravity_mps2=reference.gravity_mps2,
            effects=effects,
        )
