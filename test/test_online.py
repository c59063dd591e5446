"""The online compensator engine: first output, backlog, gaps."""

from __future__ import annotations

import numpy as np
import pytest

from tcomp_core.online import FIRST_ESTIMATE_ROWS, OnlineCompensator, OnlineConfig
from tcomp_core.reconstruct import reconstruct


def _feed(engine, pair, batch=50):
    stamps = np.round(pair.time * 1e9).astype(np.int64) + 10**18
    out_stamps, out_gas = [], []
    for start in range(0, stamps.size, batch):
        part = slice(start, start + batch)
        s, g = engine.add_pairs(stamps[part], pair.tc1[part], pair.tc2[part])
        out_stamps.append(s)
        out_gas.append(g)
    return stamps, np.concatenate(out_stamps), np.concatenate(out_gas)


def test_every_pair_is_reconstructed_once_the_first_estimate_lands(pair_factory):
    pair = pair_factory("multisine", noise_percent=1.0, seed=2, duration=2.0)
    engine = OnlineCompensator(OnlineConfig(window_s=1.0))
    stamps, out_stamps, gas = _feed(engine, pair)
    # One output per pair but the last (each output is stamped with the pair it starts).
    np.testing.assert_array_equal(out_stamps, stamps[:-1])
    assert engine.counters["unreconstructed"] == 0
    assert engine.tau is not None
    assert engine.tau[0] == pytest.approx(pair.tau1, rel=0.05)
    # The backlog was reconstructed with the first accepted τ, like everything after it.
    batch = reconstruct(pair.tc1, pair.tc2, pair.dt, *engine.tau)
    np.testing.assert_allclose(gas, batch.gas[: gas.size], rtol=1e-9)


def test_the_first_estimate_comes_after_first_estimate_rows(pair_factory):
    pair = pair_factory("multisine", noise_percent=1.0, seed=2, duration=2.0)
    engine = OnlineCompensator(OnlineConfig(window_s=1.0))
    stamps = np.round(pair.time * 1e9).astype(np.int64)
    n = FIRST_ESTIMATE_ROWS - 10
    out, _ = engine.add_pairs(stamps[:n], pair.tc1[:n], pair.tc2[:n])
    assert out.size == 0 and engine.tau is None
    out, _ = engine.add_pairs(stamps[n : n + 40], pair.tc1[n : n + 40], pair.tc2[n : n + 40])
    assert engine.tau is not None
    assert out.size == n + 40 - 1


def test_the_backlog_keeps_at_most_one_window(pair_factory):
    # A constant signal never gives an estimate: the engine holds one window, counts the rest.
    n = 3000
    stamps = np.arange(n, dtype=np.int64) * 2_000_000
    engine = OnlineCompensator(OnlineConfig(window_s=1.0))
    for start in range(0, n, 100):
        part = slice(start, start + 100)
        out, _ = engine.add_pairs(stamps[part], np.full(100, 50.0), np.full(100, 50.0))
        assert out.size == 0
    assert engine.tau is None
    held = engine._backlog_rows
    assert 500 <= held <= 600
    assert engine.counters["unreconstructed"] + held == n - 1


def test_reconstruction_matches_the_batch_reconstruction_with_the_same_tau(pair_factory):
    pair = pair_factory("ramp", noise_percent=0.5, seed=3, duration=1.0)
    engine = OnlineCompensator(OnlineConfig(window_s=0.5), initial_tau=(pair.tau1, pair.tau2))
    _, _, gas = _feed(engine, pair)
    batch = reconstruct(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2)
    np.testing.assert_allclose(gas, batch.gas[: gas.size], rtol=1e-9)
