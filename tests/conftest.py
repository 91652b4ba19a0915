"""Shared fixtures: simulated sessions with known truth."""

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from wheelcal.simulate import simulate, table1


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
