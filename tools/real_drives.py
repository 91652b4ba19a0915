"""The measured drives as the judge: calibrate them with default options and compare.

Reads the Wheel-Mounted Inertial Dataset's car trials (Xsens DOT CSV exports, as the
dataset ships them: ``<root>/trialNN/IMUk_radial.csv`` on the rim and ``IMUk.csv`` near
the hub of wheel k) — by default ``../shared/real/wid-car`` beside the project, which a
clone does not have: the script says so and stops.  Prints

1. every recording calibrated with ``wheelcal.calibrate(path)`` and no options: the
   in-plane gains and offsets, the radius, what is null and why;
2. the same sensor in two trials: Δ / σ_Δ of the radius and the in-plane gains and
   offsets (and the axle axis's), and their rms — the repeatability of Table II, on
   measured data;
3. the two sensors on one wheel: their wheel rates ω(t) and their absolute camber
   tracks γ(t) against each other, within their σ;
4. the closed loop's screen of the effects the model lacks, on each drive's fit
   (``--screen``);
5. each drive split in halves, each calibrated: Δ / σ_Δ within one drive (``--halves``).

    python tools/real_drives.py [ROOT] [--screen] [--halves]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "wid-car"
IN_PLANE = ("gain_x", "gain_y", "offset_x_mps2", "offset_y_mps2")


def _calibrate(root: Path) -> dict:
    import wheelcal

    out = {}
    for trial in sorted(p for p in root.iterdir() if p.is_dir()):
        for path in sorted(trial.glob("IMU*.csv")):
            try:
                out[(trial.name, path.stem)] = wheelcal.calibrate(path)
            except Exception as exc:  # a refusal is a result here
                out[(trial.name, path.stem)] = exc
    return out


def _axle(cal) -> str:
    along = np.abs(cal.result.params.bench.misalignment.matrix[:, 2])
    return "xyz"[int(np.argmax(along))]


def table_of_recordings(cals: dict) -> None:
    """Each recording's in-plane gains and offsets, radius and nulls (a Markdown table)."""
    print("\n## 1. Each recording, default options\n")
    print("| recording | gains (in-plane) | offsets (in-plane), m/s² | radius, m | null |")
    print("|---|---|---|---|---|")
    for (trial, stem), cal in cals.items():
        if isinstance(cal, Exception):
            print(f"| {trial}/{stem} | refused: {str(cal)[:120]} | | | |")
            continue
        r, axle = cal.result, _axle(cal)
        plane = [a for a in "xyz" if a != axle]
        nulls = dict(cal.undetermined)
        gains = ", ".join(
            f"{r.value_of(f'gain_{a}'):.4f} ± {r.std_of(f'gain_{a}'):.4f}" for a in plane
        )
        offsets = ", ".join(
            f"{r.value_of(f'offset_{a}_mps2'):+.3f} ± {r.std_of(f'offset_{a}_mps2'):.3f}"
            for a in plane
        )
        radius = f"{r.value_of('radius_m'):.4f} ± {r.std_of('radius_m'):.4f}"
        print(f"| {trial}/{stem} | {gains} | {offsets} | {radius} | {', '.join(nulls) or '—'} |")


def repeatability(cals: dict) -> None:
    """Δ / σ_Δ of each sensor's parameters between its first two trials, and their rms."""
    print("\n## 2. The same sensor in two trials: Δ / σ_Δ\n")
    trials = sorted({t for t, _ in cals})
    stems = sorted({s for _, s in cals})
    names = (
        "radius_m",
        "gain_x",
        "gain_y",
        "gain_z",
        "offset_x_mps2",
        "offset_y_mps2",
        "offset_z_mps2",
    )
    print("| sensor | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    z_plane, z_axle = [], []
    for stem in stems:
        pair = [cals.get((t, stem)) for t in trials[:2]]
        if any(c is None or isinstance(c, Exception) for c in pair):
            continue
        cells = []
        for name in names:
            a, b = pair
            if name in dict(a.undetermined) or name in dict(b.undetermined):
                cells.append("null")
                continue
            d = a.result.value_of(name) - b.result.value_of(name)
            s = np.hypot(a.result.std_of(name), b.result.std_of(name))
            z = d / s
            axle = name.endswith(_axle(a)) or name.endswith(f"{_axle(a)}_mps2")
            (z_axle if axle else z_plane).append(z)
            cells.append(f"{z:+.1f}")
        print(f"| {stem} | " + " | ".join(cells) + " |")
    zp, za = np.array(z_plane), np.array(z_axle)
    print(
        f"\nrms z, radius and in-plane gains/offsets: {np.sqrt(np.mean(zp**2)):.2f} (n {zp.size})"
    )
    if za.size:
        print(
            f"rms z, the axle axis's gain and offset: {np.sqrt(np.mean(za**2)):.2f} (n {za.size})"
        )
    allz = np.concatenate([zp, za])
    print(f"rms z, every reported gain, offset and the radius: {np.sqrt(np.mean(allz**2)):.2f}")


def _camber_series(cal):
    """(times on the recording's clock, absolute camber γ(t), its σ) of a field fit."""
    r = cal.result
    rolling = next(e for e in r.layout.effects if e.name == "rolling")
    values = r.params.effect("rolling", rolling.size)
    change = rolling.camber_change(values, rolling.time_s)
    gamma0 = np.deg2rad(90.0 - r.value_of("tilt_deg"))
    return rolling.time_s + r.centre_s, gamma0 + change, np.deg2rad(r.std_of("tilt_deg"))


def _rate_series(cal):
    from wheelcal.model.forward import wheel_kinematics

    r = cal.result
    kin = wheel_kinematics(r.params, r.centred_time_s, r.layout.effects)
    return r.centred_time_s + r.centre_s, kin.omega_radps


def two_sensors(cals: dict) -> None:
    """The hub and the rim sensor of one wheel: their ω(t) and camber γ(t) compared."""
    print("\n## 3. Two sensors on one wheel\n")
    print(
        "| trial, wheel | ω: rms difference, rad/s (of rms ω) | lag, ms "
        "| camber: mean |Δγ|, ° | Δγ / σ |"
    )
    print("|---|---|---|---|---|")
    for (trial, stem), hub in cals.items():
        if stem.endswith("_radial"):
            continue
        rim = cals.get((trial, stem + "_radial"))
        if isinstance(hub, Exception) or rim is None or isinstance(rim, Exception):
            continue
        ta, wa = _rate_series(hub)
        tb, wb = _rate_series(rim)
        lag, diff = _aligned(ta, np.abs(wa), tb, np.abs(wb))
        ca_t, ca, sa = _camber_series(hub)
        cb_t, cb, sb = _camber_series(rim)
        common = np.linspace(max(ca_t[0], cb_t[0] + lag), min(ca_t[-1], cb_t[-1] + lag), 400)
        ga = np.interp(common, ca_t, ca)
        gb = np.interp(common, cb_t + lag, cb)
        # the same camber up to the sign a frame takes (Z up at each fit's centre)
        d = min(np.mean(np.abs(ga - gb)), np.mean(np.abs(ga + gb)))
        z = d / np.hypot(sa, sb)
        print(
            f"| {trial} {stem} | {diff:.3f} ({np.sqrt(np.mean(wa**2)):.1f}) | {1e3 * lag:+.0f} | "
            f"{np.rad2deg(d):.2f} | {z:.2f} |"
        )


def _aligned(ta, xa, tb, xb) -> tuple[float, float]:
    """The lag of b on a (s) that best matches the two rates, and their rms difference then."""
    grid = np.arange(max(ta[0], tb[0]) + 1.0, min(ta[-1], tb[-1]) - 1.0, 0.005)
    a = np.interp(grid, ta, xa)
    best = (np.inf, 0.0)
    for lag in np.arange(-0.5, 0.5, 0.005):
        b = np.interp(grid, tb + lag, xb)
        err = float(np.sqrt(np.mean((a - b) ** 2)))
        best = min(best, (err, float(lag)))
    return best[1], best[0]


def screen_effects(cals: dict, alpha: float = 0.01) -> None:
    """The closed loop's screen on each drive's fit, and its strongest effect added: before/after.

    The strongest candidate significant at the family-wise ``alpha`` (Bonferroni over the
    candidates) joins the field model, which is refitted from the answer; the table gives
    how far that moves the radius and the in-plane gains and offsets, in the fit's σ.
    """
    import dataclasses

    from wheelcal.closedloop.score import screen
    from wheelcal.estimate.field.fit import FieldFit
    from wheelcal.model.effects import default_candidates

    print(
        "\n## 4. The closed loop on each drive's fit: the screen, and its strongest effect added\n"
    )
    print("| recording | strongest (p) | its shift of r, in-plane gains and offsets (σ) |")
    print("|---|---|---|")
    for (trial, stem), cal in cals.items():
        if isinstance(cal, Exception):
            continue
        r = cal.result
        present = {e.name for e in r.layout.effects}
        candidates = tuple(c for c in default_candidates() if c.name not in present)
        window = cal.session.window.recording
        tests, _ = screen(r, window, candidates)
        tests = [t for t in tests if np.isfinite(t.p_value)]
        best = min(tests, key=lambda t: t.p_value)
        if best.p_value * len(tests) > alpha:
            print(
                f"| {trial}/{stem} | none at α = {alpha:g} (best {best.effect.name}, p = "
                f"{best.p_value:.2g}) | — |"
            )
            continue
        effect = best.effect
        effects = (*r.layout.effects, effect)
        initial = r.params.with_changes(
            effects={**r.params.effects, effect.name: np.zeros(effect.size)}
        )
        rate = 1.0 / float(np.median(np.diff(window.time_s)))
        fitter = FieldFit()._joint(None, True, effects, rate)
        after = fitter.fit(dataclasses.replace(window, gyro_radps=None), initial=initial)
        axle = _axle(cal)
        names = ["radius_m"] + [
            n
            for n in IN_PLANE_NAMES
            if not n.startswith(f"gain_{axle}") and not n.startswith(f"offset_{axle}")
        ]
        shifts = ", ".join(
            f"{n} {(after.value_of(n) - r.value_of(n)) / r.std_of(n):+.1f}" for n in names
        )
        print(f"| {trial}/{stem} | {effect.name} ({best.p_value:.1g}) | {shifts} |")


def halves(root: Path) -> None:
    """Each drive split at its middle, each half calibrated: Δ / σ_Δ of the same sensor.

    The trials' spread against σ again, within one drive: a sensor that changed between
    trials (temperature) cannot be the reason where the halves disagree as much.
    """
    import wheelcal

    print("\n## 5. Each drive in halves: Δ / σ_Δ (radius, in-plane gains and offsets)\n")
    print("| recording | z |")
    print("|---|---|")
    z_all = []
    for path in sorted(root.glob("trial*/IMU*.csv")):
        rec = wheelcal.read_recording(path)
        middle = 0.5 * float(rec.time_s[0] + rec.time_s[-1])
        try:
            first = wheelcal.calibrate(rec.window(float(rec.time_s[0]), middle))
            second = wheelcal.calibrate(rec.window(middle, float(rec.time_s[-1])))
        except Exception as exc:  # a refusal is a result here
            print(f"| {path.parent.name}/{path.stem} | refused: {str(exc)[:80]} |")
            continue
        plane = [a for a in "xyz" if a != _axle(first)]
        names = ["radius_m", *(f"gain_{a}" for a in plane), *(f"offset_{a}_mps2" for a in plane)]
        a, b = first.result, second.result
        z = [(a.value_of(n) - b.value_of(n)) / np.hypot(a.std_of(n), b.std_of(n)) for n in names]
        z_all += z
        print(f"| {path.parent.name}/{path.stem} | " + " ".join(f"{v:+.1f}" for v in z) + " |")
    z = np.array(z_all)
    print(f"\nrms z of the halves: {np.sqrt(np.mean(z**2)):.2f} (n {z.size})")


IN_PLANE_NAMES = ("gain_x", "gain_y", "gain_z", "offset_x_mps2", "offset_y_mps2", "offset_z_mps2")


def main(argv=None) -> int:
    """Print the tables of the module docstring; 2 when there are no drives."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", nargs="?", default=str(ROOT))
    parser.add_argument("--screen", action="store_true", help="run the closed loop's screen")
    parser.add_argument("--halves", action="store_true", help="each drive in halves, compared")
    args = parser.parse_args(argv)
    root = Path(args.root)
    if not root.is_dir():
        print(f"{root}: no measured drives here (the WID car trials, as the dataset ships them)")
        return 2
    cals = _calibrate(root)
    table_of_recordings(cals)
    repeatability(cals)
    two_sensors(cals)
    if args.screen:
        screen_effects(cals)
    if args.halves:
        halves(root)
    return 0


if __name__ == "__main__":
    sys.exit(main())
