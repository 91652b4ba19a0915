"""The field fit's σ part by part, against the errors of simulated drives.

Calibrates simulated drives of one kind (``wheelcal.calibrate``, default options) and
splits each drive's reported covariance into the parts
:mod:`wheelcal.estimate.field.robust` adds up — the sandwich, the held nuisances'
shifts, the gyro's angle walk at the rate noise density the fit estimated — and
prices two alternatives for the walk:

* ``quiet``: the walk at the gyro's own noise, read where nothing shakes the wheel
  (the second differences of the axle's rate in the slowest tenth of 1 s blocks:
  stops and crawls) instead of over the whole drive, where a car's knuckle shakes the
  wheel in rotation (a real turn of the wheel, which the gyro reads and the angle
  integrates correctly, not an error that walks);
* ``+bias Q``: that, and the gyro's bias random walk at Q °/s/√s propagated as the
  walk is: δϑ(t) = ∫ b, b a random walk, moves the fit by Σ_m w_m δϑ(t_m), whose
  covariance is Q² Δt Σ_u V(u) V(u)ᵀ with V(u) = Σ_{t_m ≥ u} w_m (t_m − u).

It prints, per parameter, the rms over the drives of z = error / σ for each (1: σ
honest; the truth is the simulator's), so a change of the budget is measured before it
is made.  ``--without`` takes parts of a car's road out of the simulated drives (the
same drives otherwise: the scenario is drawn whole, then edited): ``shake`` (the
carrier's angular vibration), ``bias`` (the gyro's bias walk and warm-up), ``slope``
(the camber's change along the road and with the steering), ``rim`` (the rim's
vibration along the axle), ``road`` (the road itself and the rim: camber change, shake
and rim; the gyro's bias walk stays, ``bias`` takes it).  Nothing in the fit changes.

    python tools/field_sigma_budget.py car 1000:1060 [--bias-walk 0.002 0.005]
        [--without shake bias] [--workers 2]
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np

import wheelcal
import wheelcal.estimate.field.fit as field_fit
import wheelcal.estimate.field.robust as robust
from wheelcal.recording import RecordingError
from wheelcal.simulate.field import car_drive, robot_drive, simulate_field, wheelchair_coast

KINDS = {"car": car_drive, "robot": robot_drive, "wheelchair": wheelchair_coast}
#: The reported parameters judged against the truth (the rolling radius ρ is not the sensor's).
CHECKED = (
    *(f"gain_{a}" for a in "xyz"),
    *(f"offset_{a}_mps2" for a in "xyz"),
    "radius_m",
    "tilt_deg",
)
#: The quiet seconds: blocks this long, the slowest this fraction of them.
QUIET_BLOCK_S, QUIET_FRACTION = 1.0, 0.1

_SEEN: dict = {}  # one drive's parts, filled by the wrapped pieces below (one per process)


def quiet_density(time_s: np.ndarray, rate_radps: np.ndarray) -> float:
    """The rate noise density (rad/s/√Hz, as ``rate_noise_density``) in the slowest blocks.

    Blocks are chosen by their median |rate|, not by the noise itself (choosing the
    samples whose own rate is smallest picks small noise: 0.7× on a robot).
    """
    t, w = np.asarray(time_s, dtype=float), np.asarray(rate_radps, dtype=float)
    dt = float(np.median(np.diff(t)))
    n = max(8, round(QUIET_BLOCK_S / dt))
    second = w[2:] - 2.0 * w[1:-1] + w[:-2]
    blocks = second.size // n
    if blocks < 1:
        return 0.0
    speed = np.median(np.abs(w[1:-1][: blocks * n].reshape(blocks, n)), axis=1)
    quiet = np.argsort(speed)[: max(1, int(np.ceil(QUIET_FRACTION * blocks)))]
    x = second[: blocks * n].reshape(blocks, n)[quiet].ravel()
    sigma = 1.4826 * float(np.median(np.abs(x - np.median(x)))) / np.sqrt(6.0)
    return sigma * np.sqrt(dt)


def _bias_walk_per_unit(pieces, bread: np.ndarray) -> np.ndarray:
    """Δt Σ_u V(u) V(u)ᵀ: the bias walk's covariance per (rad/s/√s)² (module docstring)."""
    w = bread @ pieces.angle_score  # (P, M): the fit's answer to an angle error at each sample
    t = np.arange(w.shape[1]) * pieces.dt_s
    after = np.cumsum(w[:, ::-1], axis=1)[:, ::-1]
    after_t = np.cumsum((w * t)[:, ::-1], axis=1)[:, ::-1]
    v = after_t - after * t
    return pieces.dt_s * (v @ v.T)


def _install() -> None:
    """Wrap the fit's density and robust pass so that each drive's parts are kept."""
    density_of, robust_of = field_fit.rate_noise_density, field_fit.robust_result_with

    def density(time_s, rate_radps):
        _SEEN["quiet"] = quiet_density(time_s, rate_radps)
        return density_of(time_s, rate_radps)

    def robust_pass(result, accel_mps2, gyro_density=None, shifts=(), extension=None):
        out = robust_of(result, accel_mps2, gyro_density, shifts, extension)
        pieces = robust._pieces(result, accel_mps2, shifts, None)
        bread, finite = robust._bread(pieces)

        def std(cov):
            cov = robust._in_reported(result, robust._with_undetermined(cov, finite))
            return np.sqrt(np.clip(np.diag(cov), 0.0, None))

        parts = {"sandwich": std(robust._sandwich(pieces, bread))}
        parts["walk"] = std(robust._angle_walk(pieces, bread, gyro_density or 0.0))
        parts["walk_quiet"] = std(robust._angle_walk(pieces, bread, _SEEN.get("quiet", 0.0)))
        parts["bias_unit"] = std(_bias_walk_per_unit(pieces, bread))
        response = bread @ pieces.shift_score
        parts["shift"] = std(response @ response.T) if shifts else 0.0 * parts["sandwich"]
        _SEEN["names"], _SEEN["parts"] = list(result.names), parts
        return out

    field_fit.rate_noise_density = density
    field_fit.robust_result_with = robust_pass


def _truth(sim, name: str, centre_s: float) -> float:
    truth = sim.truth
    if name.startswith("gain_"):
        return float(truth.sensor.gain["xyz".index(name[-1])])
    if name.startswith("offset_"):
        return float(truth.sensor.offset_mps2["xyz".index(name[7])])
    return {"radius_m": truth.radius_m, "tilt_deg": truth.tilt_at_deg(centre_s)}[name]


#: What ``--without`` takes out of a drive on a road.
PARTS = ("shake", "bias", "slope", "rim", "road")


def _without(scenario, parts: tuple[str, ...]):
    """The scenario with ``parts`` of its road taken out (module docstring)."""
    road, gyro = scenario.road, scenario.gyro
    if road is None or not parts:
        return scenario
    if "road" in parts:
        return dataclasses.replace(scenario, road=None, rim_vibration=None)
    rim = None if "rim" in parts else scenario.rim_vibration
    if "shake" in parts:
        road = dataclasses.replace(road, shake_rates_radps=(0.0, 0.0, 0.0))
    if "slope" in parts:
        road = dataclasses.replace(road, cross_slope_std_deg=0.0, caster_deg=0.0)
    if "bias" in parts and gyro is not None:
        gyro = dataclasses.replace(
            gyro, bias_walk_dps_per_sqrt_s=0.0, bias_warmup_dps=(0.0, 0.0, 0.0)
        )
    return dataclasses.replace(scenario, road=road, gyro=gyro, rim_vibration=rim)


def _drive(job: tuple[str, int, tuple[str, ...]]) -> dict | None:
    """One drive: {parameter: (error, reported σ, {part: σ})}; None when refused."""
    kind, seed, without = job
    _SEEN.clear()
    rng = np.random.default_rng(seed)
    sim = simulate_field(_without(KINDS[kind](rng), without), rng)
    try:
        cal = wheelcal.calibrate(sim.recording)
    except RecordingError:
        return None
    r = cal.result
    if "parts" not in _SEEN:
        return None
    names, parts = _SEEN["names"], _SEEN["parts"]
    out = {}
    for name in CHECKED:
        if name not in names or name not in r.names or not np.isfinite(r.std_of(name)):
            continue
        k = names.index(name)
        error = r.value_of(name) - _truth(sim, name, r.centre_s)
        out[name] = (error, r.std_of(name), {p: float(v[k]) for p, v in parts.items()})
    return out


def _budgets(bias_walks: list[float]) -> dict:
    """Each alternative σ from a drive's parts (its name: a function of the parts)."""
    out = {
        "reported": None,
        "no walk": lambda p: np.hypot(p["sandwich"], p["shift"]),
        "quiet": lambda p: np.sqrt(p["sandwich"] ** 2 + p["shift"] ** 2 + p["walk_quiet"] ** 2),
    }
    for q in bias_walks:
        unit = np.deg2rad(q)
        out[f"+bias {q:g}"] = lambda p, u=unit: np.sqrt(
            p["sandwich"] ** 2 + p["shift"] ** 2 + p["walk_quiet"] ** 2 + (u * p["bias_unit"]) ** 2
        )
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the table of the module docstring for one kind's drives."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("kind", choices=sorted(KINDS))
    parser.add_argument("seeds", help="A:B, the drives' seeds A … B − 1")
    parser.add_argument("--bias-walk", type=float, nargs="*", default=[0.002, 0.005])
    parser.add_argument("--without", nargs="*", choices=PARTS, default=[])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    first, last = map(int, args.seeds.split(":"))
    _install()
    jobs = [(args.kind, seed, tuple(args.without)) for seed in range(first, last)]
    context = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(args.workers, mp_context=context) as pool:
        drives = [d for d in pool.map(_drive, jobs) if d]
    without = f" without {', '.join(args.without)}" if args.without else ""
    print(f"{args.kind}{without}: {len(drives)} of {len(jobs)} drives calibrated; rms of error / σ")
    budgets = _budgets(args.bias_walk)
    print("| parameter | n | " + " | ".join(budgets) + " |")
    print("|---|---|" + "---|" * len(budgets))
    for name in CHECKED:
        rows = [d[name] for d in drives if name in d]
        if not rows:
            continue
        cells = []
        for f in budgets.values():
            z = [e / (s if f is None else f(p)) for e, s, p in rows]
            cells.append(f"{np.sqrt(np.mean(np.square(z))):.2f}")
        print(f"| {name} | {len(rows)} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
