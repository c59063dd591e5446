"""The fast second-order-section helpers give scipy's results bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from tcomp_core import sections


@pytest.mark.parametrize("order", [1, 2, 4, 5, 8])
@pytest.mark.parametrize("kind", ["lowpass", "highpass"])
def test_sosfilt_from_is_scipys_sosfilt(order: int, kind: str) -> None:
    rng = np.random.default_rng(order)
    sos = signal.butter(order, 0.07, btype=kind, output="sos")
    values = rng.standard_normal(3001).cumsum()
    zi = rng.standard_normal((sos.shape[0], 2))
    expected = signal.sosfilt(sos, values, zi=zi)[0]
    found = sections.sosfilt_from(sos, values, zi)
    assert np.array_equal(found, expected)
    # Its arguments are left as they were; a reversed view filters like a copy.
    assert np.array_equal(zi, np.asarray(zi))
    assert np.array_equal(
        sections.sosfilt_from(sos, values[::-1], zi), signal.sosfilt(sos, values[::-1], zi=zi)[0]
    )


@pytest.mark.parametrize("order", [1, 2, 4, 5])
@pytest.mark.parametrize("size", [40, 1000, 4097])
def test_zero_phase_is_scipys_sosfiltfilt(order: int, size: int) -> None:
    rng = np.random.default_rng(size + order)
    sos = signal.butter(order, 0.11, output="sos")
    values = 20.0 + rng.standard_normal(size).cumsum()
    assert np.array_equal(sections.zero_phase(sos, values), signal.sosfiltfilt(sos, values))
    assert np.array_equal(sections.ZeroPhase(sos)(values), signal.sosfiltfilt(sos, values))


def test_zero_phase_raises_as_scipy_on_a_short_series() -> None:
    sos = signal.butter(4, 0.1, output="sos")
    with pytest.raises(ValueError, match="padlen"):
        sections.zero_phase(sos, np.ones(15))


def test_the_public_stand_in_filters_as_the_kernel() -> None:
    rng = np.random.default_rng(7)
    sos = signal.butter(3, 0.2, output="sos")
    values = rng.standard_normal((1, 500))
    zi = rng.standard_normal((1, sos.shape[0], 2))
    x1, z1 = values.copy(), zi.copy()
    x2, z2 = values.copy(), zi.copy()
    sections._public_kernel(sos, x1, z1)
    sections._KERNEL(sos, x2, z2)
    assert np.array_equal(x1, x2)
    assert np.array_equal(z1, z2)
