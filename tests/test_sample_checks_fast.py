"""The faster forms of the sample checks against numpy's straightforward ones, bit for bit.

``rows_all``/``rows_any`` replace ``mask.all(axis=1)``/``mask.any(axis=1)``;
``_block_mean_std`` replaces ``blocks.mean(axis=1)``/``blocks.std(axis=1)`` in
``rest_level``; the per-axis extremes of ``_drop_clipped`` come from a
contiguous copy.  The straightforward forms are the oracle.
"""

import numpy as np
import pytest

from wheelcal.recording import samples as sample_checks
from wheelcal.recording.samples import InputPolicy, clean_samples, rows_all, rows_any


@pytest.mark.parametrize("width", [1, 2, 3, 4])
def test_rows_all_and_any_equal_numpys_reductions(width):
    rng = np.random.default_rng(width)
    for p in (0.0, 0.02, 0.5, 0.98, 1.0):
        mask = rng.random((1000, width)) < p
        np.testing.assert_array_equal(rows_all(mask), mask.all(axis=1))
        np.testing.assert_array_equal(rows_any(mask), mask.any(axis=1))
    # and they never write into their argument
    mask = rng.random((50, width)) < 0.5
    before = mask.copy()
    rows_all(mask)
    rows_any(mask)
    np.testing.assert_array_equal(mask, before)


@pytest.mark.parametrize("seed", range(5))
def test_block_mean_std_are_numpys_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 400))
    scale = 10.0 ** rng.integers(-3, 4)
    blocks = rng.normal(9.8, 1.0, (m, 50, 3)) * scale + rng.normal(0, 1e-3, (m, 1, 3))
    mean, std = sample_checks._block_mean_std(blocks.copy())
    assert np.array_equal(mean, blocks.mean(axis=1))
    assert np.array_equal(std, blocks.std(axis=1))


def _rest_level_plain(accel, block=50):
    n = accel.shape[0] // block
    if n == 0:
        return None
    blocks = accel[: n * block].reshape(n, block, 3)
    level = np.linalg.norm(blocks.mean(axis=1), axis=1)
    spread = blocks.std(axis=1).max(axis=1)
    quiet = (level > 0) & (spread < 0.02 * level)
    if quiet.sum() < 2:
        return None
    return float(np.median(level[quiet]))


def test_rest_level_is_the_plain_computations():
    rng = np.random.default_rng(7)
    for n in (49, 50, 5000, 40_000):  # 40 000 rows: several pieces
        at_rest = rng.normal([0.1, 0.2, 9.8], 0.01, (n, 3))
        spinning = at_rest + 5.0 * np.sin(np.arange(n) / 7.0)[:, None]
        for accel in (at_rest, spinning, at_rest / 9.80665):
            assert sample_checks.rest_level(accel) == _rest_level_plain(accel)


def test_clipping_and_outliers_find_what_the_row_reductions_find(monkeypatch):
    rng = np.random.default_rng(11)
    n = 6000
    t = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000
    phase = np.arange(n) * 2 * np.pi / 40
    a = np.stack([15 + 11 * np.cos(phase), 20 * np.sin(phase), np.full(n, 9.8)], axis=1)
    a += rng.normal(0, 0.05, a.shape)
    a[:, 0] = np.minimum(a[:, 0], 25.0)  # a rail on x
    a[100, 1] = 400.0  # a gross outlier
    a[200] = np.nan  # a NaN row

    def plain_rows_all(mask):
        return mask.all(axis=1)

    def plain_rows_any(mask):
        return mask.any(axis=1)

    policy = InputPolicy()
    fast = clean_samples("f", t, a, unit="m/s^2", full_scale_g=None, policy=policy)
    ranged = clean_samples("f", t, a, unit="m/s^2", full_scale_g=2.55, policy=policy)
    with monkeypatch.context() as m:
        m.setattr(sample_checks, "rows_all", plain_rows_all)
        m.setattr(sample_checks, "rows_any", plain_rows_any)
        plain = clean_samples("f", t, a, unit="m/s^2", full_scale_g=None, policy=policy)
        plain_ranged = clean_samples("f", t, a, unit="m/s^2", full_scale_g=2.55, policy=policy)
    for got, want in ((fast, plain), (ranged, plain_ranged)):
        np.testing.assert_array_equal(got.time_ns, want.time_ns)
        np.testing.assert_array_equal(got.accel_mps2, want.accel_mps2)
        assert got.notes == want.notes
        np.testing.assert_array_equal(got.clip_limits_mps2, want.clip_limits_mps2)
    assert any("clipped" in note for note in fast.notes)
    assert any("outlier" in note for note in fast.notes)
    assert any("NaN" in note for note in fast.notes)
    assert any("sensor range" in note for note in ranged.notes)
    assert fast.clip_limits_mps2[0, 1] == 25.0  # the rail, found on the contiguous copy


def test_the_small_steps_shortcut_never_changes_the_outlier_search(monkeypatch):
    """When the largest step is below the floor, the full search finds nothing either."""
    rng = np.random.default_rng(19)
    policy = InputPolicy()
    floor = policy.outlier_floor_g * 9.80665
    taken = {True: 0, False: 0}
    for trial in range(300):
        n = int(rng.integers(5, 3000))
        step = floor * rng.choice([0.1, 0.45, 0.9, 0.999, 1.001, 1.5])  # near the bound too
        a = np.cumsum(rng.uniform(-step, step, (n, 3)), axis=0)
        if trial % 4 == 0:  # a spike: just beyond the floor (its own step), or far
            a[rng.integers(n), rng.integers(3)] += (
                rng.choice([-1, 1]) * floor * rng.choice([1.2, 1.9, 30])
            )
        if trial % 17 == 0:
            a[rng.integers(n), 0] = 2e4  # beyond any accelerometer
        t = np.arange(n, dtype=np.int64) * 5_000_000
        shortcut = sample_checks._steps_too_small_for_outliers(a, floor, 1000 * 9.80665)
        taken[shortcut] += 1
        got = _outcome(sample_checks._drop_gross_outliers, t, a, policy)
        with monkeypatch.context() as m:
            m.setattr(sample_checks, "_steps_too_small_for_outliers", lambda *args: False)
            want = _outcome(sample_checks._drop_gross_outliers, t, a, policy)
        assert got[0] == want[0]
        if got[0] == "ok":
            np.testing.assert_array_equal(got[1], want[1])
            np.testing.assert_array_equal(got[2], want[2])
            assert got[3] == want[3]
    assert min(taken.values()) > 50


def _outcome(drop, t, a, policy):
    notes = []
    try:
        t2, a2 = drop("f", t, a, policy, notes)
    except sample_checks.SampleError as exc:
        return ("refused", str(exc))
    return ("ok", t2, a2, notes)
