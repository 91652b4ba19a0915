"""Every second with motion counts: a wheel pushed three times, with a gyro (issue 38).

With default options (``wheelcal.calibrate``, ``--gyro auto``) a recording whose
free spin is a small part of the motion the gyroscope measures is fitted whole:
the pushes between the spin-downs are joined (the disturbance check cuts what a
hand does), the wheel angle follows the pushes as a spline, and the summary
lists the stretches fitted.  Judged against the simulator's truth:

* every gain and offset within 5 σ_CRLB at the truth (the bound of the model
  fitted, ``loop_truth.py``);
* σ ≤ 1.3× those of an *unpushed* spin of the same length and speed law (the same
  generator, ``pushes_profile(…, pushes=1)``: one spin-down over the 90 s);
* a clean hand spin (its free spin is nearly all of its motion) keeps the
  accelerometer's own answer, exactly (``test_gyro_accuracy``).

Pushes as the simulator draws them (0.8 s, ≤ 7 rad/s²) and fast ones (0.3 s,
~15 rad/s², which the window's 8 rad/s² limit cuts out: the stretches are joined
across them).  CI: two recordings; ``-m slow``: 12.
"""

from __future__ import annotations

import numpy as np
import pytest

import wheelcal
from loop_truth import SENSOR, bound_in, sigmas_from_truth
from wheelcal.session.window import find_motion_window
from wheelcal.simulate import hostile
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.motion import pushes_profile

LIMIT_SIGMA = 5.0
SIGMA_RATIO = 1.3


def _pair(seed: int, push_s: float):
    """A wheel pushed three times, and one spun once with the same speed law (same length)."""
    rng = np.random.default_rng(seed)
    pushed = hostile.driven(
        rng, pushes_profile(rng, 90.0, pushes=3, push_s=push_s), "three pushes", gyro=GyroSpec()
    )
    rng = np.random.default_rng(10_000 + seed)
    unpushed = hostile.driven(rng, pushes_profile(rng, 90.0, pushes=1), "unpushed", gyro=GyroSpec())
    return pushed, unpushed


def _judge(seed: int, push_s: float):
    pushed, unpushed = _pair(seed, push_s)
    cal = wheelcal.calibrate(pushed.recording)
    reference = wheelcal.calibrate(unpushed.recording)
    z = sigmas_from_truth(pushed, cal.result)
    std = np.array([cal.result.std_of(n) for n in SENSOR])
    std_ref = np.array([reference.result.std_of(n) for n in SENSOR])
    crlb = np.array([bound_in(pushed, cal.result).std_of(n) for n in SENSOR])
    return cal, reference, z, std / std_ref, std / crlb


@pytest.mark.parametrize(("seed", "push_s"), [(0, 0.8), (1, 0.3)])
def test_three_pushes_are_fitted_whole_by_default(seed, push_s):
    cal, reference, z, ratio, honest = _judge(seed, push_s)
    source = cal["source"]
    assert "whole motion is fitted" in source["window_reason"], source["window_reason"]
    assert cal["motion"]["model"] == "polynomial3+spline"
    stretches = source["fitted_stretches_s"]
    assert len(stretches) >= 3, stretches  # the pushes between the spin-downs were cut
    assert sum(b - a for a, b in stretches) > 75.0, stretches  # of ~90 s of motion
    assert f"fitted {len(stretches)} stretches" in source["window_reason"]
    # The unpushed spin keeps the free spin: the accelerometer's own answer.
    assert reference["source"]["window_reason"].startswith("free spin")
    assert max(abs(v) for v in z.values()) < LIMIT_SIGMA, z
    assert np.all(ratio <= SIGMA_RATIO), dict(zip(SENSOR, ratio.round(3), strict=True))
    assert np.all((honest > 0.9) & (honest < 1.1)), honest  # σ is the bound


def test_the_motion_window_joins_the_stretches_across_fast_pushes():
    pushed, _ = _pair(1, 0.3)
    found = find_motion_window(pushed.recording)
    assert found.duration_s > 85.0, found.reason
    # A push faster than 8 rad/s² cuts the wheel's turning into stretches; the longest
    # alone was ≤ 60 s, the window joins them all.
    assert "stretches where the wheel turns, joined across" in found.reason, found.reason


def test_the_summary_lists_the_fitted_stretches(tmp_path, capsys):
    from wheelcal.cli.main import main
    from wheelcal.io import write_recording

    pushed, _ = _pair(0, 0.8)
    path = tmp_path / "pushed.mcap"
    write_recording(pushed.recording, path)
    assert main(["calibrate", str(path), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "the whole motion is fitted" in out and "fitted 3 stretches" in out, out


@pytest.mark.slow
def test_three_pushes_monte_carlo():
    ratios, worst = [], []
    for seed in range(12):
        _, _, z, ratio, honest = _judge(100 + seed, (0.8, 0.3)[seed % 2])
        ratios.append(ratio)
        worst.append(max(abs(v) for v in z.values()))
        assert np.all((honest > 0.9) & (honest < 1.1)), honest
    ratios = np.array(ratios)
    print("worst σ_CRLB", np.round(worst, 2), "σ ratio max per parameter", ratios.max(axis=0))
    assert max(worst) < LIMIT_SIGMA, worst
    assert np.all(ratios <= SIGMA_RATIO), ratios.max(axis=0)
