"""Shared fixtures: seeded simulated two-thermocouple records and a seeded generator."""

from __future__ import annotations

import numpy as np
import pytest
from sim_records import make_pair


@pytest.fixture
def pair_factory():
    return make_pair


@pytest.fixture
def rng():
    return np.random.default_rng(20050101)
