"""Mutation check: do the CI tests notice deliberate errors in the physics and the σ.

Applies each deliberate error of issue 12's audit to a temporary copy of the
repository (the tracked files of the working tree), runs the CI test selection
(``pytest`` with the project's default options, i.e. everything not ``slow``)
against that copy, and reports which tests fail.  A mutation that no test
catches is a hole in the suite: the script exits 1 when any survives.

    python tools/mutation_check.py                    # all mutations, stop each run at 1st failure
    python tools/mutation_check.py --all-failures     # full runs: every failing test is listed
    python tools/mutation_check.py --only sigma_x1.25 --tests tests/test_accuracy.py
    python tools/mutation_check.py --baseline         # the unmutated copy must pass first

Each mutation is a set of exact text replacements; each replacement must match
exactly once, so a refactor that moves the code makes the check fail loudly
instead of testing nothing.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Replacement:
    """Replace ``old`` (which must occur exactly once) by ``new`` in ``path``."""

    path: str
    old: str
    new: str


@dataclass(frozen=True)
class Mutation:
    """A named deliberate error: one or more replacements applied together."""

    name: str
    description: str
    replacements: tuple[Replacement, ...]


_INFO = "src/wheelcal/estimate/joint/information.py"
_EFFECTS = "src/wheelcal/model/effects.py"
_ROLLING = "src/wheelcal/model/rolling.py"
_GYRO_SIM = "src/wheelcal/simulate/gyro.py"
_BENCH = "src/wheelcal/model/bench.py"
_FORWARD = "src/wheelcal/model/forward.py"
_COV_LINE = "    cov = (v[:, keep] / w[keep]) @ v[:, keep].T / np.outer(scale, scale)\n"


def _scale_sigma(factor: float) -> tuple[Replacement, ...]:
    variance = factor * factor
    return (Replacement(_INFO, _COV_LINE, _COV_LINE.rstrip("\n") + f" * {variance!r}\n"),)


MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "sigma_x1.25",
        "every reported σ and the CRLB at the truth ×1.25 (information.py, one line)",
        _scale_sigma(1.25),
    ),
    Mutation(
        "sigma_x0.8",
        "every reported σ and the CRLB at the truth ×0.8 (information.py, one line)",
        _scale_sigma(0.8),
    ),
    Mutation(
        "tangential_sign",
        "sign of the tangential term r·ω̇ (model, Jacobian and Jᵀu, consistently)",
        (
            Replacement(
                _BENCH,
                "a[:, 1] = radius_m * kin.omega_dot_radps2 + g_sin * s",
                "a[:, 1] = -radius_m * kin.omega_dot_radps2 + g_sin * s",
            ),
            Replacement(
                _BENCH, "out[:, 1] = kin.omega_dot_radps2", "out[:, 1] = -kin.omega_dot_radps2"
            ),
            Replacement(
                _FORWARD,
                "day += radius_m * d_omega_dot",
                "day -= radius_m * d_omega_dot",
            ),
            Replacement(
                _FORWARD,
                "np.multiply(u[1], r, out=rows[2])",
                "np.multiply(u[1], -r, out=rows[2])",
            ),
            Replacement(
                _FORWARD,
                "kin.omega_radps**2 @ u[0] + kin.omega_dot_radps2 @ u[1]",
                "kin.omega_radps**2 @ u[0] - kin.omega_dot_radps2 @ u[1]",
            ),
        ),
    ),
    Mutation(
        "centripetal_sign",
        "sign of the centripetal term r·ω² (model, Jacobian and Jᵀu, consistently)",
        (
            Replacement(
                _BENCH,
                "a[:, 0] = radius_m * kin.omega_radps**2 + g_sin * c",
                "a[:, 0] = -radius_m * kin.omega_radps**2 + g_sin * c",
            ),
            Replacement(
                _BENCH, "out[:, 0] = kin.omega_radps**2", "out[:, 0] = -kin.omega_radps**2"
            ),
            Replacement(
                _FORWARD,
                "dax += d_omega * ((2 * radius_m) * omega)",
                "dax -= d_omega * ((2 * radius_m) * omega)",
            ),
            Replacement(
                _FORWARD,
                "rows[1] *= 2 * r",
                "rows[1] *= -2 * r",
            ),
            Replacement(
                _FORWARD,
                "kin.omega_radps**2 @ u[0] + kin.omega_dot_radps2 @ u[1]",
                "-kin.omega_radps**2 @ u[0] + kin.omega_dot_radps2 @ u[1]",
            ),
        ),
    ),
    Mutation(
        "gravity_sin_sign",
        "sign of g·sinα·sinϑ in a_Y (model, Jacobian and Jᵀu, consistently)",
        (
            Replacement(
                _BENCH,
                "a[:, 1] = radius_m * kin.omega_dot_radps2 + g_sin * s",
                "a[:, 1] = radius_m * kin.omega_dot_radps2 - g_sin * s",
            ),
            Replacement(
                _BENCH,
                "out[:, 1] = force.g_cos_tilt * force.sin_theta",
                "out[:, 1] = -force.g_cos_tilt * force.sin_theta",
            ),
            Replacement(
                _BENCH,
                "out[:, 1] = np.sin(tilt_rad) * force.sin_theta",
                "out[:, 1] = -np.sin(tilt_rad) * force.sin_theta",
            ),
            Replacement(
                _FORWARD,
                "np.multiply(d_theta, force.g_sin_tilt * force.cos_theta, out=day)",
                "np.multiply(d_theta, -force.g_sin_tilt * force.cos_theta, out=day)",
            ),
            Replacement(
                _FORWARD,
                "force.g_sin_tilt * (force.cos_theta * u[1] - force.sin_theta * u[0])",
                "force.g_sin_tilt * (-force.cos_theta * u[1] - force.sin_theta * u[0])",
            ),
            Replacement(
                _FORWARD,
                "force.cos_theta @ u[0] + force.sin_theta @ u[1]",
                "force.cos_theta @ u[0] - force.sin_theta @ u[1]",
            ),
        ),
    ),
    Mutation(
        "gyro_reading_sign",
        "the simulated gyro reads +ω R e_Z instead of −ω R e_Z (the gyro's sign convention)",
        (
            Replacement(
                _GYRO_SIM,
                "axis = -np.asarray(misalignment, dtype=float)[:, 2]",
                "axis = np.asarray(misalignment, dtype=float)[:, 2]",
            ),
        ),
    ),
    Mutation(
        "rolling_travel_sign",
        "sign of a rolling wheel's travel term ρ·ω̇ (model and its partials, consistently)",
        (
            Replacement(
                _ROLLING,
                "return self.Pd * self.sg - self.wd",
                "return self.Pd * self.sg + self.wd",
            ),
            Replacement(
                _ROLLING,
                "return self._stack(rho * s, -rho * c, np.zeros_like(s))",
                "return self._stack(-rho * s, rho * c, np.zeros_like(s))",
            ),
        ),
    ),
    Mutation(
        "imbalance_rate_sign",
        "sign of an imbalance's rate ripple Δω (its value, own rows and partials, consistently)",
        (
            Replacement(_EFFECTS, "d_omega = -du / w\n", "d_omega = du / w\n"),
            Replacement(
                _EFFECTS,
                "own_omega = np.vstack([-c / w, s / w])",
                "own_omega = np.vstack([c / w, -s / w])",
            ),
            Replacement(
                _EFFECTS,
                "np.negative(omega[0], out=omega[0])\n"
                "        np.multiply(sin_theta, inv, out=omega[1])",
                "np.multiply(sin_theta, -inv, out=omega[1])",
            ),
            Replacement(
                _EFFECTS,
                "by_theta = (-du / w**2, u / w, du)",
                "by_theta = (-du / w**2, -u / w, du)",
            ),
            Replacement(
                _EFFECTS,
                "by_omega = (2 * u / w**3, du / w**2, np.zeros_like(u))",
                "by_omega = (2 * u / w**3, -du / w**2, np.zeros_like(u))",
            ),
        ),
    ),
    Mutation(
        "gyro_rest_frame",
        "a rest's force taken through R instead of Rᵀ (the gyro's and the screen's rests)",
        (
            Replacement(
                "src/wheelcal/model/parameters.py",
                "return relative @ self.bench.misalignment.matrix  #",
                "return relative @ self.bench.misalignment.matrix.T  #",
            ),
        ),
    ),
    Mutation(
        "g_shift_whole_camber",
        "the gyro angle's camber in G's shift takes the new track whole (what the basis holds too)",
        (
            Replacement(
                "src/wheelcal/estimate/field/fit.py",
                "angle_track = effect.camber_track_rad + _beyond_basis(change, rolling)",
                "angle_track = effect.camber_track_rad + change",
            ),
        ),
    ),
    Mutation(
        "field_lags_one_second",
        "the sandwich's lags stay at one second whatever the blocks' own correlation says",
        (
            Replacement(
                "src/wheelcal/estimate/field/robust.py",
                "    out[live] = np.minimum(each, int(MAX_LAG_FRACTION * blocks))",
                "    out[live] = 0",
            ),
        ),
    ),
    Mutation(
        "field_lags_median_for_all",
        "every parameter's σ at the median of the lags, not at its own",
        (
            Replacement(
                "src/wheelcal/estimate/field/robust.py",
                "    own = own_lag_variances(bread @ block_scores, own_lags) + np.diag(prior)",
                "    own = own_lag_variances(bread @ block_scores, np.full_like(own_lags, lags))"
                " + np.diag(prior)",
            ),
        ),
    ),
    Mutation(
        "field_track_read_once",
        "the camber's track read once, at the first pass's wheel angle, not again at each pass's",
        (
            Replacement(
                "src/wheelcal/estimate/field/fit.py",
                "        read = build.series_at(gyro_radps, series.oriented, next_x[:n], rotation)",
                "        read = series",
            ),
        ),
    ),
    Mutation(
        "field_passes_damped",
        "the camber's passes take the damped step only (no Anderson mixing of the passes before)",
        (
            Replacement(
                "src/wheelcal/estimate/field/fit.py",
                "ANDERSON_DEPTH = 3\n",
                "ANDERSON_DEPTH = 0\n",
            ),
        ),
    ),
    Mutation(
        "gyro_matrix_transposed",
        "the pooled gyro fit measures Mᵀ d instead of M d along each mounting's wheel axis",
        (
            Replacement(
                "src/wheelcal/closedloop/gyro_matrix.py",
                "a[0:3, _M] = np.kron(_E, self.axis)",
                "a[0:3, _M] = np.kron(self.axis, _E)",
            ),
        ),
    ),
    Mutation(
        "gyro_correction_transposed",
        "apply corrects the gyro with (M⁻¹)ᵀ instead of M⁻¹",
        (
            Replacement(
                "src/wheelcal/calibration/gyro_apply.py",
                "return g @ np.ascontiguousarray(self.matrix.T)",
                "return g @ np.ascontiguousarray(self.matrix)",
            ),
        ),
    ),
    Mutation(
        "gyro_simulator_transposed",
        "the simulator's gyro reads Mᵀ Ω instead of M Ω",
        (
            Replacement(
                _GYRO_SIM,
                "rate = ideal @ self.response_matrix.T",
                "rate = ideal @ self.response_matrix",
            ),
        ),
    ),
)


@dataclass(frozen=True)
class RunResult:
    """Outcome of one pytest run on a (possibly mutated) copy."""

    name: str
    returncode: int
    failed: tuple[str, ...]
    summary: str
    seconds: float


def _copy_tree(destination: Path) -> None:
    """Copy the tracked files of the working tree (as they are now) to ``destination``."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        check=True,
        capture_output=True,
    ).stdout.split(b"\0")
    for raw in listed:
        if not raw:
            continue
        relative = raw.decode()
        source = REPO / relative
        if not source.is_file():
            continue
        target = destination / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(source, target)


def _apply(copy: Path, mutation: Mutation) -> None:
    for rep in mutation.replacements:
        path = copy / rep.path
        text = path.read_text()
        count = text.count(rep.old)
        if count != 1:
            raise SystemExit(
                f"mutation {mutation.name}: {rep.path} holds {count} copies of {rep.old!r} "
                "(expected exactly 1) — update tools/mutation_check.py to the current code"
            )
        path.write_text(text.replace(rep.old, rep.new))


_FAILED = re.compile(r"^(?:FAILED|ERROR) (\S+)", re.MULTILINE)
_SUMMARY = re.compile(r"^=+ (.*(?:passed|failed|error).*) =+$", re.MULTILINE)


def _run_pytest(copy: Path, name: str, tests: list[str], stop_first: bool) -> RunResult:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(copy / "src") + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    where = subprocess.run(
        [sys.executable, "-c", "import wheelcal; print(wheelcal.__file__)"],
        cwd=copy,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    if not where.startswith(str(copy)):
        raise SystemExit(f"the copy's wheelcal is not the one imported ({where})")
    # The check of the mutations' own texts reads the mutated copy, where each mutation's text
    # is gone by design: it would "catch" every mutation that no physics test does.
    ignore = f"--ignore={copy / 'tests' / 'test_mutation_check.py'}"
    # In one process (-n 0): the suite's workers take their files in large shares, so that
    # -x stopped a mutant only after 1243 of its tests (772 s) where in order it stops early.
    command = [sys.executable, "-m", "pytest", "-q", "-rfE", "-p", "no:cacheprovider", "-n", "0"]
    command.append(ignore)
    command += tests
    if stop_first:
        command.append("-x")
    start = time.perf_counter()
    done = subprocess.run(command, cwd=copy, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    failed = tuple(dict.fromkeys(_FAILED.findall(done.stdout)))
    summaries = _SUMMARY.findall(done.stdout)
    tail = (done.stdout.strip().splitlines() or ["(no output)"])[-1]
    summary = summaries[-1] if summaries else tail
    return RunResult(name, done.returncode, failed, summary, seconds)


def _check(name: str, mutation: Mutation | None, tests: list[str], stop_first: bool) -> RunResult:
    with tempfile.TemporaryDirectory(prefix=f"wheelcal-mutant-{name}-") as tmp:
        copy = Path(tmp)
        _copy_tree(copy)
        if mutation is not None:
            _apply(copy, mutation)
        return _run_pytest(copy, name, tests, stop_first)


def main(argv: list[str] | None = None) -> int:
    """Run the chosen mutations; exit status 1 when one survives."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", action="append", default=[], help="run only this mutation")
    parser.add_argument("--tests", nargs="*", default=[], help="pytest arguments (default: CI)")
    parser.add_argument(
        "--all-failures", action="store_true", help="run each suite fully and list every failure"
    )
    parser.add_argument(
        "--baseline", action="store_true", help="first check that the unmutated copy passes"
    )
    parser.add_argument("--list", action="store_true", help="list the mutations and exit")
    args = parser.parse_args(argv)
    if args.list:
        for m in MUTATIONS:
            print(f"{m.name:18s} {m.description}")
        return 0
    chosen = [m for m in MUTATIONS if not args.only or m.name in args.only]
    unknown = set(args.only) - {m.name for m in MUTATIONS}
    if unknown:
        parser.error(f"unknown mutation(s): {', '.join(sorted(unknown))}")
    stop_first = not args.all_failures
    if args.baseline:
        base = _check("baseline", None, args.tests, stop_first)
        print(f"baseline: {base.summary} in {base.seconds:.0f} s", flush=True)
        if base.returncode != 0:
            print("the unmutated copy fails: fix that first", file=sys.stderr)
            return 1
    rows = []
    for mutation in chosen:
        result = _check(mutation.name, mutation, args.tests, stop_first)
        rows.append((mutation, result))
        caught = "caught" if result.failed else "SURVIVED"
        print(
            f"{mutation.name}: {caught} — {result.summary} in {result.seconds:.0f} s",
            flush=True,
        )
        for test in result.failed[:12]:
            print(f"    {test}", flush=True)
    print()
    scope = "first failure" if stop_first else "failing CI tests"
    print(f"| deliberate error | {scope} | run time (s) |")
    print("|---|---|---|")
    for mutation, result in rows:
        shown = (
            f"{len(result.failed)}: " + ", ".join(t.split("::")[-1] for t in result.failed[:3])
            if result.failed
            else "**none**"
        )
        if not stop_first and len(result.failed) > 3:
            shown += ", …"
        print(f"| {mutation.description} | {shown} | {result.seconds:.0f} |")
    survivors = [m.name for m, r in rows if not r.failed]
    if survivors:
        print(f"\nsurvived: {', '.join(survivors)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
