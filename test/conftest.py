"""Shared fixtures: seeded simulated two-thermocouple records and a seeded generator.

Also pins BLAS to one thread per test process (and the processes tests start), before numpy
loads: the matrices here are small, and on a 2-core machine shared with other work OpenBLAS's
spinning worker threads made the fitting tests about five times slower (a signal-model fit:
18 s against 3.3 s). A value set in the environment wins.

Marks every test under ``test/ros/`` ``realtime`` (pyproject.toml): ``make test`` runs those one
at a time, beside the others.
"""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest
from sim_records import make_pair

#: The launch-free rclpy tests: nodes over DDS, kept to the wall clock.
ROS_TESTS = Path(__file__).parent / "ros"


@pytest.hookimpl(tryfirst=True)  # before ``-m`` selects by the markers
def pytest_collection_modifyitems(items):
    for item in items:
        if ROS_TESTS in item.path.parents:
            item.add_marker(pytest.mark.realtime)


@pytest.fixture
def pair_factory():
    return make_pair


@pytest.fixture
def rng():
    return np.random.default_rng(20050101)
