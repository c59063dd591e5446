"""β-GTLS cost: streaming 3×3 scatter matrix vs. the paper's SVD of the N×3 data matrix.

What is measured, for each record length N (samples per thermocouple):

(a) ``scatter`` – :func:`tcomp_core.estimators.beta.beta_gtls`: the 3×3 scatter matrix
    ``[X Y]ᵀ [X Y]`` of Eq. (14) accumulated in chunks of ``CHUNK_ROWS`` rows, then a 3×3
    generalized eigenproblem with C0(φ=1) of Eq. (19). O(N) time, O(1) extra memory.
(b) ``SVD`` – the paper's route (Eqs. 15, 18–21), written out here as the baseline: build the
    full (N-1)×3 matrix ``S = [X Y]``, weight it by ``W⁻¹`` where ``C0 = WᵀW`` (Cholesky),
    take ``np.linalg.svd(S @ W⁻¹, full_matrices=False)``, map the right singular vector of the
    smallest singular value back with ``g = W⁻¹ v_min`` and read ``θ = -g[:2] / g[2]`` (Eq. 21),
    then β, b1 (Eq. 17), the poles and τ1, τ2. O(N) time, O(N) extra memory.
(c) ``window`` – :class:`tcomp_core.window.SlidingBetaWindow` with ``capacity=5000`` built and
    fed the whole record through ``extend`` in chunks of 10 000 samples, then one
    ``estimate()``. Its memory does not depend on N. (Chunks longer than the capacity take the
    window's reset path: the scatter of the last ``capacity`` samples is recomputed per chunk.
    For N < capacity the record arrives as one ``extend`` into an empty window; if the estimate
    then fails, the error is printed under the table and time/memory are still reported.)

Reported per method:

* wall time (``time.perf_counter``), best of several repeats for small N, one repeat for large
  N, measured with tracemalloc off;
* ``peak MiB`` – tracemalloc peak during one separate call, i.e. the extra Python/numpy heap the
  call needed (inputs are allocated beforehand and not counted). NumPy's data buffers are traced,
  but the LAPACK workspace ``np.linalg.svd`` allocates with plain ``malloc`` (a column-major copy
  of the matrix plus the U work array, about 2 × N×3 floats) is *not*; the tracemalloc figure
  therefore understates the SVD route. To show the real footprint the table also gives
* ``RSS MiB`` – the rise of the process's resident-set high-water mark (``VmHWM``, reset through
  ``/proc/self/clear_refs``) during the first timed call; Linux only, ``n/a`` elsewhere.

The agreement of (a) and (b) is checked: ``rel diff`` is ``max(|Δτ1|/τ1, |Δτ2|/τ2)`` between the
two routes (they solve the same GTLS problem, so it should be at rounding level).

Input: one sinusoid record (10 Hz, 100 ± 50 °C) through the exact ZOH sensor model with the
paper's τ1 = 0.0238 s, τ2 = 0.1168 s, sampled at dt = 0.0002 s, 1 % white noise (Eq. 22, φ = 1),
simulated once with :func:`tcomp_core.simulate.simulate_pair` for the largest N; smaller N use a
prefix of it (the noise σ follows the std of the whole record, so the τ printed at a given N
shift slightly with the largest N requested). Generation is not timed.

Run::

    cd /work/main && PYTHONPATH=. .venv/bin/python bench/bench_scatter_vs_svd.py
    PYTHONPATH=. .venv/bin/python bench/bench_scatter_vs_svd.py --quick
    PYTHONPATH=. .venv/bin/python bench/bench_scatter_vs_svd.py --sizes 2500 1e6
"""

from __future__ import annotations

import argparse
import gc
import math
import sys
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tcomp_core.errors import TcompError
from tcomp_core.estimators.beta import beta_gtls, beta_noise_covariance
from tcomp_core.models import pole_to_tau
from tcomp_core.simulate import PAPER_TAU1, PAPER_TAU2, simulate_pair
from tcomp_core.window import SlidingBetaWindow

DT = 0.0002
NOISE_PERCENT = 1.0
WINDOW_CAPACITY = 5000
WINDOW_CHUNK = 10_000
DEFAULT_SIZES = (2500, 10_000, 100_000, 1_000_000, 10_000_000)
QUICK_SIZES = (2500, 10_000, 100_000)
MIB = float(1 << 20)
_STATUS = Path("/proc/self/status")
_CLEAR_REFS = Path("/proc/self/clear_refs")


# --------------------------------------------------------------------------- the three routes


def beta_gtls_svd(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float, phi: float = 1.0
) -> tuple[float, float]:
    """β-GTLS the paper's way: SVD of the weighted full data matrix (Eqs. 15, 18–21).

    Returns
    -------
    tau1, tau2 : float
        Time constants in seconds.
    """
    # Eq. (15): S = [X Y], X = [ΔT_m1(k), T_m1(k-1) - T_m2(k-1)], Y = ΔT_m2(k); (N-1)×3.
    s_matrix = np.column_stack((tc1[1:] - tc1[:-1], tc1[:-1] - tc2[:-1], tc2[1:] - tc2[:-1]))
    # Eqs. (18)–(19): C0 = WᵀW with W the (upper) Cholesky factor.
    weight = np.linalg.cholesky(beta_noise_covariance(phi)).T
    weight_inv = np.linalg.inv(weight)
    # Eq. (20): min ‖S g‖ / ‖W g‖ — with h = W g this is the plain SVD of S W⁻¹.
    _, _, vt = np.linalg.svd(s_matrix @ weight_inv, full_matrices=False)
    g = weight_inv @ vt[-1]  # generalized singular vector of the smallest value
    theta = -g[:2] / g[2]  # Eq. (21): [θ; -1] = -g / g₃
    beta, b1 = theta[0], theta[1] / theta[0]  # Eq. (17)
    a1, a2 = 1.0 - b1, 1.0 - beta * b1
    return pole_to_tau(a1, dt, "svd: a1"), pole_to_tau(a2, dt, "svd: a2")


def beta_gtls_scatter(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float
) -> tuple[float, float]:
    """β-GTLS through the project's chunked 3×3 scatter matrix."""
    estimate = beta_gtls(tc1, tc2, dt)
    return estimate.tau1, estimate.tau2


#: Errors raised by the window's estimate, keyed by N (reported under the table).
WINDOW_ERRORS: dict[int, str] = {}


def beta_gtls_window(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float
) -> tuple[float, float]:
    """Sliding window of WINDOW_CAPACITY samples fed the whole record, then one estimate.

    An estimation error is recorded in WINDOW_ERRORS (τ returned as NaN) so that the time and
    memory of the window are still measured.
    """
    window = SlidingBetaWindow(WINDOW_CAPACITY, dt)
    for start in range(0, tc1.size, WINDOW_CHUNK):
        window.extend(tc1[start : start + WINDOW_CHUNK], tc2[start : start + WINDOW_CHUNK])
    try:
        estimate = window.estimate()
    except TcompError as exc:
        WINDOW_ERRORS[tc1.size] = f"{type(exc).__name__}: {exc}"
        return math.nan, math.nan
    return estimate.tau1, estimate.tau2


# --------------------------------------------------------------------------- measurement

Route = Callable[[NDArray[np.float64], NDArray[np.float64], float], tuple[float, float]]


def _status_mib(key: str) -> float:
    for line in _STATUS.read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024.0
    raise KeyError(key)


def _rss_probe_available() -> bool:
    try:
        _CLEAR_REFS.write_text("5")
        _status_mib("VmHWM")
    except (OSError, KeyError):
        return False
    return True


RSS_PROBE = _rss_probe_available()


def time_route(
    route: Route, tc1: NDArray[np.float64], tc2: NDArray[np.float64], repeats: int
) -> tuple[float, float, tuple[float, float]]:
    """Best wall time over ``repeats`` calls and the RSS high-water rise of the first call."""
    best = math.inf
    rss_rise = math.nan
    result: tuple[float, float] = (math.nan, math.nan)
    for index in range(repeats):
        gc.collect()
        if index == 0 and RSS_PROBE:
            _CLEAR_REFS.write_text("5")  # reset VmHWM to the current RSS
            before = _status_mib("VmRSS")
        start = time.perf_counter()
        result = route(tc1, tc2, DT)
        elapsed = time.perf_counter() - start
        if index == 0 and RSS_PROBE:
            rss_rise = max(_status_mib("VmHWM") - before, 0.0)
        best = min(best, elapsed)
    return best, rss_rise, result


def traced_peak(route: Route, tc1: NDArray[np.float64], tc2: NDArray[np.float64]) -> float:
    """Tracemalloc peak (MiB) of the allocations made during one call."""
    gc.collect()
    tracemalloc.start()
    try:
        route(tc1, tc2, DT)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return peak / MIB


def repeats_for(n: int, quick: bool) -> int:
    if quick:
        return 3
    if n <= 100_000:
        return 7
    if n <= 1_000_000:
        return 3
    return 1


def make_record(n_max: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One simulated noisy sinusoid record of at least ``n_max`` samples (not timed)."""
    pair = simulate_pair(
        "sinusoid",
        tau1=PAPER_TAU1,
        tau2=PAPER_TAU2,
        dt=DT,
        duration=(n_max + 1) * DT,
        noise_percent=NOISE_PERCENT,
        seed=0,
    )
    # Keep only the two noisy signals; drop time, gas and clean copies.
    return pair.tc1[:n_max].copy(), pair.tc2[:n_max].copy()


def parse_size(text: str) -> int:
    value = float(text.replace("_", ""))
    if not (value.is_integer() and value >= 16):
        raise argparse.ArgumentTypeError(f"{text!r} is not a sample count >= 16")
    return int(value)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="β-GTLS: streaming 3×3 scatter vs. SVD of the N×3 data matrix."
    )
    parser.add_argument(
        "--sizes",
        type=parse_size,
        nargs="+",
        metavar="N",
        help="record lengths (accepts 1e6, 10_000); default "
        + ", ".join(f"{n:_}" for n in DEFAULT_SIZES),
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"fast run: sizes {', '.join(f'{n:_}' for n in QUICK_SIZES)} (unless --sizes), "
        "3 repeats",
    )
    args = parser.parse_args(argv)
    sizes = sorted(set(args.sizes or (QUICK_SIZES if args.quick else DEFAULT_SIZES)))

    tc1_all, tc2_all = make_record(max(sizes))
    # Warm-up (imports, LAPACK initialisation, heap growth) outside the measurements.
    for route in (beta_gtls_scatter, beta_gtls_svd, beta_gtls_window):
        route(tc1_all[:WINDOW_CHUNK], tc2_all[:WINDOW_CHUNK], DT)
    gc.collect()
    print(
        f"β-GTLS, sinusoid 10 Hz, dt={DT} s, τ1={PAPER_TAU1} s, τ2={PAPER_TAU2} s, "
        f"noise K={NOISE_PERCENT} %, φ=1; window capacity {WINDOW_CAPACITY}, "
        f"chunks {WINDOW_CHUNK}"
    )
    print(f"numpy {np.__version__}; times in seconds (best of r), memory in MiB")
    header = (
        f"{'N':>12} {'r':>2} | {'scatter s':>10} {'SVD s':>10} {'speed-up':>9} "
        f"{'window s':>10} | {'scatter pk':>10} {'SVD pk':>9} {'window pk':>9} | "
        f"{'scat RSS':>8} {'SVD RSS':>8} | {'rel diff':>9} | {'τ1 (a)':>8} {'τ2 (a)':>8}"
    )
    print(header)
    print("-" * len(header))
    speedups: dict[int, float] = {}
    for n in sizes:
        tc1, tc2 = tc1_all[:n], tc2_all[:n]
        repeats = repeats_for(n, args.quick)
        t_scatter, rss_scatter, tau_scatter = time_route(beta_gtls_scatter, tc1, tc2, repeats)
        t_svd, rss_svd, tau_svd = time_route(beta_gtls_svd, tc1, tc2, repeats)
        t_window, _, _ = time_route(beta_gtls_window, tc1, tc2, repeats)
        peak_scatter = traced_peak(beta_gtls_scatter, tc1, tc2)
        peak_svd = traced_peak(beta_gtls_svd, tc1, tc2)
        peak_window = traced_peak(beta_gtls_window, tc1, tc2)
        rel_diff = max(
            abs(tau_scatter[0] - tau_svd[0]) / abs(tau_svd[0]),
            abs(tau_scatter[1] - tau_svd[1]) / abs(tau_svd[1]),
        )
        speedups[n] = t_svd / t_scatter
        print(
            f"{n:>12_} {repeats:>2} | {t_scatter:>10.4g} {t_svd:>10.4g} "
            f"{speedups[n]:>8.1f}× {t_window:>10.4g} | {peak_scatter:>10.3f} "
            f"{peak_svd:>9.1f} {peak_window:>9.3f} | {rss_scatter:>8.1f} {rss_svd:>8.1f} | "
            f"{rel_diff:>9.1e} | {tau_scatter[0]:>8.5f} {tau_scatter[1]:>8.5f}",
            flush=True,
        )
    for n, message in WINDOW_ERRORS.items():
        print(f"window estimate failed at N={n:_} (time/memory still measured): {message}")
    if not RSS_PROBE:
        print("(RSS columns n/a: /proc/self/clear_refs not available)")
    target = 1_000_000
    if target in speedups:
        verdict = "yes" if speedups[target] >= 5.0 else "NO"
        print(f"speed-up at N=1e6: {speedups[target]:.1f}× — at least 5×: {verdict}")
    else:
        print("speed-up at N=1e6: not measured (add 1e6 to --sizes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
