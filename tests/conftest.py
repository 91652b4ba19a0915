"""Shared fixtures: simulated sessions with known truth."""

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from wheelcal.io.mcap_writer import recording_stamps_ns
from wheelcal.recording import SessionInfo
from wheelcal.simulate import Scenario, simulate, table1, table2
from wheelcal.simulate.session import SessionPlan, simulate_session


@pytest.fixture(scope="session")
def table1_session():
    """One Table I recording at σ_n = 0.08 m/s² (seed 11)."""
    return simulate(table1(), np.random.default_rng(11))


@pytest.fixture(scope="session", autouse=True)
def single_threaded_blas():
    """One BLAS thread and the tuned allocator, as the CLI uses (see wheelcal.runtime)."""
    from wheelcal.runtime import tune_allocator

    tune_allocator()
    with threadpool_limits(1):
        yield


@pytest.fixture(scope="module")
def base():
    """Bad-input tests: a short whole session (rest, push, 20 s spin, brake, rest) at 200 Hz.

    Returns the stamps (ns) and the samples (m/s²), to be damaged and written.
    """
    truth = table2(rng=np.random.default_rng(8)).truth
    scenario = Scenario(truth=truth, duration_s=20.0, info=SessionInfo(radius_m=0.28))
    sim = simulate_session(scenario, np.random.default_rng(9), SessionPlan(rest_before_s=3.0))
    rec = sim.recording
    return recording_stamps_ns(rec), rec.accel_mps2.copy()
