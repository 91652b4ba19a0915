"""The gates refuse no good data, and the rests catch what the spin's residual cannot (issue 11).

* **No false refusals**: random realistic setups (the accuracy tests' generator,
  in whole sessions with rests, push and stop) and the paper's Table I/II
  presets are all accepted.  The random setups also give no warning about an
  unexplained residual, and the rest check's false alarms stay within its
  family-wise α = 1 % (binomial: ≤ 6 of 200 at the 0.995 quantile).
* **Rest check**: an offset warm-up and a quadratic nonlinearity leave the spin's
  residual at the noise floor (no "unexplained" warning), but the rests no longer
  read |a| = g after calibration.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from truth_bound import sigmas_off
from wheelcal.model.effects import OffsetWarmup, QuadraticNonlinearity
from wheelcal.session.fit import SessionFit
from wheelcal.simulate import random_setup, simulate_session, table1, table2


def _session(seed: int):
    rng = np.random.default_rng(seed)
    return simulate_session(random_setup(rng), rng)


def _kinds(warnings) -> dict[str, int]:
    kinds = {"unexplained": 0, "rest": 0, "motion": 0}
    for w in warnings:
        if "left unexplained" in w:
            kinds["unexplained"] += 1
        if w.startswith("at rest"):
            kinds["rest"] += 1
    return kinds


def _accept_all(seeds):
    refused, rest_alarms, unexplained, worst = [], 0, 0, []
    for seed in seeds:
        session = _session(seed)
        try:
            result = SessionFit().run(session.recording)
        except Exception as exc:  # counted and reported, not hidden
            refused.append((seed, str(exc)))
            continue
        kinds = _kinds(result.warnings)
        rest_alarms += kinds["rest"] > 0
        unexplained += kinds["unexplained"]
        worst.append(max(sigmas_off(session, result).values()))
    return refused, rest_alarms, unexplained, worst


def test_random_realistic_setups_are_accepted_short():
    refused, rest_alarms, unexplained, worst = _accept_all(range(700, 712))
    assert not refused, refused
    assert unexplained == 0
    assert rest_alarms <= 1
    assert max(worst) < 5.0, worst


@pytest.mark.slow
def test_random_realistic_setups_are_accepted_full():
    n = 200
    refused, rest_alarms, unexplained, worst = _accept_all(range(n))
    assert len(refused) <= 1, refused
    assert unexplained == 0
    assert rest_alarms <= stats.binom.ppf(0.995, n, 0.01), rest_alarms
    assert max(worst) < 5.0, sorted(worst)[-5:]


@pytest.mark.parametrize("preset", ["table1", "table2"])
def test_the_papers_presets_pass_with_at_most_warnings(preset):
    rng = np.random.default_rng(31)
    scenario = table1() if preset == "table1" else table2(rng=rng)
    session = simulate_session(scenario, rng)
    result = SessionFit().run(session.recording)
    assert result.undetermined == ()
    assert max(sigmas_off(session, result).values()) < 5.0
    assert _kinds(result.warnings)["unexplained"] == 0
    if preset == "table1":  # gains 0.9/1.1 and offsets of 1 m/s² are beyond datasheet tolerances
        assert any("gain_x = 0.9" in w for w in result.warnings), result.warnings
        assert any("offset_" in w and "mg" in w for w in result.warnings), result.warnings
    else:
        assert not result.warnings, result.warnings


def _with_effect(effect, values, seed: int):
    rng = np.random.default_rng(seed)
    scenario = table2(rng=rng)
    truth = scenario.truth.with_changes(effects={effect.name: values})
    scenario = dataclasses.replace(scenario, truth=truth, effects=(effect,))
    return simulate_session(scenario, rng)


def _warmup_amplitude(d_mps2, tau_s: float, centre_s: float):
    """a of a(1 − e^{−t/τ}) (centred t) for d(1 − e^{−t'/τ}) from power-on at t' = 0."""
    return list(np.asarray(d_mps2) * np.exp(-centre_s / tau_s))


@pytest.mark.parametrize("seed", [41, 42, 43])
def test_the_rests_catch_an_offset_warmup_the_spin_residual_hides(seed):
    tau, centre = 25.0, 4.8 + 45.0  # the session puts the free spin's centre here
    values = _warmup_amplitude([0.08, -0.05, 0.1], tau, centre)
    session = _with_effect(OffsetWarmup(tau), values, seed)
    result = SessionFit().run(session.recording)
    kinds = _kinds(result.warnings)
    assert kinds["unexplained"] == 0, result.warnings
    assert kinds["rest"] >= 1, result.warnings
    flagged = [c for c in result.assessment.rest_checks if c.flagged]
    assert flagged and all(abs(c.z) > 4 for c in flagged)


@pytest.mark.parametrize("seed", [51, 52, 53])
def test_the_rests_catch_a_nonlinearity_the_spin_residual_hides(seed):
    session = _with_effect(QuadraticNonlinearity(2), [1e-3], seed)
    result = SessionFit().run(session.recording)
    kinds = _kinds(result.warnings)
    assert kinds["unexplained"] == 0, result.warnings
    assert kinds["rest"] >= 1, result.warnings


def test_rest_check_z_is_standard_normal_on_clean_sessions():
    # The check's σ is honest: on clean sessions z has mean ≈ 0 and std ≈ 1
    # (40 seeds × 2 rests: std within ±25 %, mean within ±0.5).
    zs = []
    for seed in range(800, 840):
        result = SessionFit().run(_session(seed).recording)
        zs += [c.z for c in result.assessment.rest_checks]
    zs = np.array(zs)
    assert zs.size >= 60
    assert abs(zs.mean()) < 0.5, zs.mean()
    assert 0.75 < zs.std(ddof=1) < 1.25, zs.std(ddof=1)


class _Fitted:
    """What the post-fit gates read of a calibration (the values and σ by name)."""

    def __init__(self, values: dict, stds: dict | None = None, fitted_radius: bool = True):
        from types import SimpleNamespace

        self._values, self._stds = values, stds or {}
        self.source, self.converged = "<drive>", True
        self.params = SimpleNamespace(bench=SimpleNamespace(radius_m=0.15))
        self.layout = SimpleNamespace(fit_radius=fitted_radius)

    def value_of(self, name: str) -> float:
        return self._values[name]

    def std_of(self, name: str) -> float:
        return self._stds.get(name, 0.001)


_SOUND = {"gain_x": 1.003, "gain_y": 0.998, "gain_z": 1.01}
_OFFSETS = {"offset_x_mps2": 0.1, "offset_y_mps2": -0.05, "offset_z_mps2": 0.2}


def test_an_axis_implausible_on_its_own_is_null_and_the_rest_calibrated():
    # A real drive's axle axis: gain_z 0.0151 (σ 0.046, under the datasheet tolerance, so
    # "determined") while x and y read 1.003, 1.004 — the whole drive was refused as
    # gain_range; and an offset of 0.35 g on one axis alone likewise.
    from wheelcal.recording import CalibrationRefused
    from wheelcal.session.gates import Gates, refuse_implausible

    gates = Gates()
    fit = _Fitted({**_SOUND, "gain_z": 0.0151, **_OFFSETS}, {"gain_z": 0.046})
    nulled = dict(refuse_implausible(fit, gates, []))
    assert set(nulled) == {"gain_z"}
    assert "0.0151" in nulled["gain_z"] and "x 1.003, y 0.998" in nulled["gain_z"]
    fit = _Fitted({**_SOUND, **_OFFSETS, "offset_y_mps2": 3.5})
    assert set(dict(refuse_implausible(fit, gates, []))) == {"offset_y_mps2"}
    # every gain off by one factor is a radius (or a unit): still refused, and the
    # message says the radius was fitted, not given
    fit = _Fitted({"gain_x": 2.6, "gain_y": 2.55, "gain_z": 2.62, **_OFFSETS})
    with pytest.raises(CalibrationRefused) as refused:
        refuse_implausible(fit, gates, [])
    assert refused.value.gate == "gain_range" and "the radius the fit found" in str(refused.value)
    # a range the user narrowed is theirs: a determined gain outside it refuses
    fit = _Fitted({**_SOUND, "gain_y": 0.994, **_OFFSETS})
    with pytest.raises(CalibrationRefused) as refused:
        refuse_implausible(fit, Gates(gain_range=(0.995, 1.02)), [])
    assert refused.value.gate == "gain_range"
    # so are offsets that are all implausible
    fit = _Fitted({**_SOUND, "offset_x_mps2": 4.0, "offset_y_mps2": -3.5, "offset_z_mps2": 3.3})
    with pytest.raises(CalibrationRefused) as refused:
        refuse_implausible(fit, gates, [])
    assert refused.value.gate == "offset_range"
