"""The estimator orchestrates itself (issue 41 item 2): what session/ asks of the joint fit.

session/ sequences a session's steps and reaches the estimator only through the
joint fit's front: no chunk size, quadrature rule, whitening or gyro equation is
imported there.  The pieces that moved behind the front keep their numbers: the
start's implied mean gain is r_implied / r (the radius check before fitting), a
refit without a knock leaves out the knock and lands where the clean fit does.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
from pathlib import Path

import numpy as np
import pytest

import wheelcal
from wheelcal.estimate.joint import JointFit, clear_of_rails, without_disturbances
from wheelcal.simulate import simulate, table1

SESSION = Path(wheelcal.__file__).parent / "session"
#: The joint fit's building blocks: the closed loop and the planner assemble their own
#: normal equations from them; a session never does.
BUILDING_BLOCKS = {
    "CHUNK_SAMPLES",
    "NormalEquations",
    "QuadratureRows",
    "accumulate",
    "accumulate_gyro",
    "gyro_effect",
    "gyro_samples",
    "quadrature_hessian",
    "quadrature_rows",
    "stride_for",
    "whitened_back",
    "whitened_rows",
}


def _estimate_names_imported_by_session() -> set[str]:
    names = set()
    for path in SESSION.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(
                "wheelcal.estimate"
            ):
                names |= {alias.name for alias in node.names}
    return names


def test_session_imports_no_building_block_of_the_fit():
    assert _estimate_names_imported_by_session() & BUILDING_BLOCKS == set()


def test_no_session_module_sums_normal_equations():
    assert not (SESSION / "motion_quadrature.py").exists()
    text = (SESSION / "motion_check.py").read_text(encoding="utf-8")
    for word in ("whiten(", "evaluate(", "spin_columns", "cubic_bspline_slots"):
        assert word not in text, word


@functools.cache
def _bench():
    return simulate(table1(), np.random.default_rng(5))


def test_implied_mean_gain_is_the_implied_radius_over_the_radius():
    recording = _bench().recording
    guess = JointFit().start(recording)
    radius = recording.info.radius_m
    assert guess.implied_radius_m is not None
    gain = guess.implied_mean_gain(radius)
    assert gain == guess.implied_radius_m / radius
    # The bench's gains average 1 within a few per cent: the start sees that already.
    assert gain == pytest.approx(1.0, abs=0.05)
    # mm typed as m: the start puts the gains 1000× off, before any fit.
    assert guess.implied_mean_gain(radius * 1000) == pytest.approx(gain / 1000, rel=1e-12)
    assert guess.implied_mean_gain(None) is None
    assert dataclasses.replace(guess, implied_radius_m=None).implied_mean_gain(radius) is None


def test_a_clean_fit_is_left_as_it_is():
    recording = _bench().recording
    fit = JointFit().fit(recording)
    refit, kept, note = without_disturbances(JointFit(), fit, recording)
    assert refit is fit and kept is recording and note == ""
    # Rails far beyond the bench's ±2 g: the model puts no sample near them.
    railed = dataclasses.replace(
        recording, clip_limits_mps2=np.array([[-1e3, 1e3]] * 3, dtype=float)
    )
    refit, kept, note = clear_of_rails(JointFit(), fit, railed)
    assert refit is fit and kept is railed and note == ""


def test_a_knock_is_left_out_and_the_refit_lands_where_the_clean_fit_does():
    recording = _bench().recording
    clean = JointFit().fit(recording)
    rng = np.random.default_rng(9)
    t = recording.time_s
    knock = (t > t[0] + 20.0) & (t < t[0] + 21.0)
    accel = recording.accel_mps2.copy()
    accel[knock] += rng.normal(0.0, 3.0, (int(knock.sum()), 3))
    knocked = dataclasses.replace(recording, accel_mps2=accel)
    fit = JointFit().fit(knocked)
    refit, kept, note = without_disturbances(JointFit(), fit, knocked)
    assert "left out" in note
    left_out = np.setdiff1d(t, kept.time_s)
    assert np.all(np.isin(t[knock], left_out)), "every knocked sample is left out"
    # The knock and a block on each side (0.5 s blocks): at most 1 s + 2 × 0.5 s + 2 blocks.
    assert 1.0 <= left_out.size / recording.rate_hz <= 3.0
    for name in ("gain_x", "gain_y", "gain_z", "offset_x_mps2", "offset_y_mps2", "offset_z_mps2"):
        i = clean.names.index(name)
        assert abs(refit.values[i] - clean.values[i]) < 3 * clean.std[i], name
