"""Named scenarios: the paper's Table I and Table II, and random hand spins.

``table1`` — the truth of the paper's Table I (r = 0.28 m, 200 Hz, 90 s).  The
paper does not state its time origin.  Its σ for the motion parameters match
the Cramér–Rao bound (within ~2×) only with t measured from the *first sample*
— although ω(t) then dips near 65 s and rises again, which no real wheel does
(centred, the same coefficients would fall from 13.9 to 6.1 rad/s and the bound
would be 10× tighter than the paper's σ).  So the preset is defined with t from
the first sample, :data:`TABLE1_SPIN_FROM_START`, and converted to the
contract's centre-time parameters with :meth:`SpinParams.shifted`.  The Euler
angles θ, φ, ψ of Table I are read in :data:`~wheelcal.model.EULER_CONVENTION`.

``table2`` — tilt, misalignment, gains and offsets of Table II (the paper's
MPU-9250), noise 0.08 m/s², with a different hand spin each draw.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from wheelcal.model import BenchParams, CalibrationParams, Rotation, SensorParams, SpinParams
from wheelcal.simulate.noise import NoiseSpec
from wheelcal.simulate.simulator import Scenario

#: Table I motion with t = 0 at the first sample: ϑ₀ = 30°, ω₀ = 9 rad/s,
#: ω₁ = −90 mrad/s², ω₂ = 500 µrad/s³, ω₃ = 2 µrad/s⁴.
TABLE1_SPIN_FROM_START = SpinParams(
    theta0_rad=np.deg2rad(30.0), omega_radps=(9.0, -90e-3, 500e-6, 2e-6)
)
TABLE1_DURATION_S = 90.0
TABLE1_EULER_DEG = (30.0, 20.0, 25.0)
TABLE1_TILT_DEG = 45.0
TABLE1_GAIN = (0.9, 1.0, 1.1)
TABLE1_OFFSET_MPS2 = (1.0, -1.0, 1.0)

TABLE2_TILT_DEG = 46.111
TABLE2_EULER_DEG = (24.760, 7.311, 31.974)
TABLE2_GAIN = (1.00952, 0.99420, 1.02752)
TABLE2_OFFSET_MPS2 = (0.1413, -0.0679, -0.3186)
TABLE2_RADIUS_M = 0.280


def table1(noise: NoiseSpec | None = None, rng: np.random.Generator | None = None) -> Scenario:
    """The paper's Table I truth, in centre time (see the module docstring)."""
    del rng  # deterministic truth
    truth = CalibrationParams(
        spin=TABLE1_SPIN_FROM_START.shifted(TABLE1_DURATION_S / 2),
        bench=BenchParams(
            tilt_rad=np.deg2rad(TABLE1_TILT_DEG),
            radius_m=0.28,
            misalignment=Rotation.from_euler_deg(*TABLE1_EULER_DEG),
        ),
        sensor=SensorParams(offset_mps2=TABLE1_OFFSET_MPS2, gain=TABLE1_GAIN),
    )
    return Scenario(
        truth=truth, duration_s=TABLE1_DURATION_S, rate_hz=200.0, noise=noise or NoiseSpec(0.08)
    )


def hand_spin(
    rng: np.random.Generator,
    duration_s: float,
    start_radps: tuple[float, float] = (9.0, 13.0),
    end_ratio: tuple[float, float] = (0.55, 0.85),
    direction: int | None = None,
    degree: int = 3,
) -> SpinParams:
    """A random hand spin: quadratic air drag, ω̇ = −c ω², fitted by eq. (2).

    ω(t) = ω_s / (1 + c ω_s t) from ω_s to ``end_ratio``·ω_s over the window;
    the returned cubic (centre time) is the truth, so the paper's model is exact.
    """
    omega_start = rng.uniform(*start_radps)
    ratio = rng.uniform(*end_ratio)
    drag = (1.0 / ratio - 1.0) / (omega_start * duration_s)
    t = np.linspace(0.0, duration_s, 2001)
    omega = omega_start / (1.0 + drag * omega_start * t)
    coeffs = np.polynomial.polynomial.polyfit(t - duration_s / 2, omega, degree)
    sign = direction if direction is not None else (1 if rng.random() < 0.5 else -1)
    return SpinParams(theta0_rad=rng.uniform(-np.pi, np.pi), omega_radps=sign * coeffs)


def table2(noise: NoiseSpec | None = None, rng: np.random.Generator | None = None) -> Scenario:
    """Table II's bench and sensor with a random hand spin (needs ``rng``)."""
    if rng is None:
        raise ValueError("table2 draws a different hand spin each time: pass rng")
    truth = CalibrationParams(
        spin=hand_spin(rng, 90.0, direction=1),
        bench=BenchParams(
            tilt_rad=np.deg2rad(TABLE2_TILT_DEG),
            radius_m=TABLE2_RADIUS_M,
            misalignment=Rotation.from_euler_deg(*TABLE2_EULER_DEG),
        ),
        sensor=SensorParams(offset_mps2=TABLE2_OFFSET_MPS2, gain=TABLE2_GAIN),
    )
    return Scenario(truth=truth, duration_s=90.0, rate_hz=200.0, noise=noise or NoiseSpec(0.08))


def random_rotation(rng: np.random.Generator) -> Rotation:
    """A rotation drawn uniformly (Haar measure)."""
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return Rotation(
        np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
    )


def random_setup(
    rng: np.random.Generator, noise: NoiseSpec | None = None, min_axis_angle_deg: float = 15.0
) -> Scenario:
    """A random but sensible bench: tilt 10°–85°, either spin direction, 60–120 s, 100–1000 Hz.

    The mounting is drawn uniformly and redrawn while any sensor axis lies within
    ``min_axis_angle_deg`` of a bench axis (such mountings leave gains unobservable).
    """
    while True:
        rot = random_rotation(rng)
        cosines = np.abs(rot.matrix)  # |cos| between sensor axis i and bench axis j
        if np.all(cosines < np.cos(np.deg2rad(min_axis_angle_deg))):
            break
    duration = float(rng.uniform(60.0, 120.0))
    truth = CalibrationParams(
        spin=hand_spin(rng, duration, start_radps=(6.0, 14.0)),
        bench=BenchParams(
            tilt_rad=np.deg2rad(rng.uniform(10.0, 85.0)),
            radius_m=rng.uniform(0.15, 0.35),
            misalignment=rot,
        ),
        sensor=SensorParams(offset_mps2=rng.uniform(-0.5, 0.5, 3), gain=rng.uniform(0.95, 1.05, 3)),
    )
    return Scenario(
        truth=truth,
        duration_s=duration,
        rate_hz=float(rng.choice([100.0, 200.0, 400.0, 500.0, 1000.0])),
        noise=noise or NoiseSpec(0.08),
    )


PRESETS: dict[str, Callable[..., Scenario]] = {"table1": table1, "table2": table2}


def preset(
    name: str, noise: NoiseSpec | None = None, rng: np.random.Generator | None = None
) -> Scenario:
    """A named scenario: ``table1`` or ``table2``."""
    try:
        factory = PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose from {sorted(PRESETS)}") from None
    return factory(noise=noise, rng=rng)
