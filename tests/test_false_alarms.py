"""The closed loop on exact-model recordings: false additions at most α, answers unchanged.

Random realistic whole sessions (the accuracy tests' generator: tilt 10°–85°,
either spin direction, 60–120 s, 100–1000 Hz, gains ±5 %, offsets ±0.5 m/s²;
rests around the spin, which the screen uses) hold exactly the paper's model.
The default calibration must add an effect in at most a fraction α = 1 % of
them (family-wise, Bonferroni over the candidates), refuse none, and where it
adds nothing give the paper's model's numbers (within 0.1 σ: in fact the same
fit).  CI runs 20 sessions; ``-m slow`` runs 200.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from wheelcal.session.compute import SessionOptions
from wheelcal.simulate import random_setup, simulate_session

ALPHA = 0.01


def _run(seeds) -> tuple[list[int], float]:
    """Sessions where the loop added an effect; the largest change elsewhere (σ)."""
    default = SessionOptions().session_fit()
    paper = SessionOptions(model="paper").session_fit()
    added, moved = [], 0.0
    for seed in seeds:
        rng = np.random.default_rng(seed)
        recording = simulate_session(random_setup(rng), rng).recording
        loop = default.run(recording)  # a refusal raises: refusing good data fails the test
        if loop.diagnosis.steps:
            added.append(seed)
            continue
        bare = paper.run(recording).result
        change = np.abs(loop.result.values - bare.values) / bare.std
        moved = max(moved, float(np.max(change)))
    return added, moved


def _allowed(n: int) -> int:
    """The most additions a family-wise level α allows in n sessions (one-sided, 0.1 %)."""
    return int(stats.binom.ppf(0.999, n, ALPHA))


def test_clean_sessions_gain_no_effect_short():
    added, moved = _run(range(20))
    assert len(added) <= _allowed(20), added
    assert moved < 0.1, moved


@pytest.mark.slow
def test_clean_sessions_gain_no_effect():
    added, moved = _run(range(200))
    print(f"effects added in {len(added)}/200 clean sessions (α = {ALPHA}): {added}")
    assert len(added) <= _allowed(200), added
    assert moved < 0.1, moved
