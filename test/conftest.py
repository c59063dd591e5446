"""Shared fixtures: seeded simulated two-thermocouple records and a seeded generator.

Also pins BLAS to one thread per test process (and the processes tests start), before numpy
loads: the matrices here are small, and on a 2-core machine shared with other work OpenBLAS's
spinning worker threads made the fitting tests about five times slower (a signal-model fit:
18 s against 3.3 s). A value set in the environment wins.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest
from sim_records import make_pair


@pytest.fixture
def pair_factory():
    return make_pair


@pytest.fixture
def rng():
    return np.random.default_rng(20050101)
