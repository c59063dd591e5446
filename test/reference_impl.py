"""Slow textbook reference implementations of the estimators, for cross-checking tcomp_core.

Written from the paper (Hung, Irwin, Kee & McLoone 2005, Sec. III) without using any of
tcomp_core's scatter-matrix / generalized-eigenproblem machinery: every regression builds the
explicit N×3 (β) or N×4 (γ) augmented matrix [X Y] and solves it with ``np.linalg.lstsq`` or the
SVD, as the paper did. The TDR-Kee reference loops over samples in Python.

Not collected by pytest (no ``test_`` prefix).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import savgol_filter

# --------------------------------------------------------------------------------------------
# Regression matrices in the paper's form
# --------------------------------------------------------------------------------------------


def gamma_matrices(tc1, tc2):
    """X (N-1)×3 = [T_m2(k-1), T_m1(k), T_m1(k-1)] and Y = T_m2(k) of Eq. (11)."""
    tc1 = np.asarray(tc1, dtype=np.float64)
    tc2 = np.asarray(tc2, dtype=np.float64)
    n = tc1.size
    x = np.zeros((n - 1, 3))
    y = np.zeros(n - 1)
    for row, k in enumerate(range(1, n)):
        x[row, 0] = tc2[k - 1]
        x[row, 1] = tc1[k]
        x[row, 2] = tc1[k - 1]
        y[row] = tc2[k]
    return x, y


def beta_matrices(tc1, tc2):
    """X (N-1)×2 and Y (N-1) of Eqs. (14)–(15).

    Y = T_m2(k) - T_m2(k-1); X = [T_m1(k) - T_m1(k-1), T_m1(k-1) - T_m2(k-1)].
    """
    tc1 = np.asarray(tc1, dtype=np.float64)
    tc2 = np.asarray(tc2, dtype=np.float64)
    n = tc1.size
    x = np.zeros((n - 1, 2))
    y = np.zeros(n - 1)
    for row, k in enumerate(range(1, n)):
        x[row, 0] = tc1[k] - tc1[k - 1]
        x[row, 1] = tc1[k - 1] - tc2[k - 1]
        y[row] = tc2[k] - tc2[k - 1]
    return x, y


def c0_matrix(phi):
    """Eq. (19), typed in from the paper."""
    return np.array(
        [
            [2 * phi, -phi, 0],
            [-phi, phi + 1, 1],
            [0, 1, 2],
        ],
        dtype=np.float64,
    )


# --------------------------------------------------------------------------------------------
# Solvers
# --------------------------------------------------------------------------------------------


def ls_solve(x, y):
    theta, *_ = np.linalg.lstsq(x, y, rcond=None)
    return theta


def tls_solve(x, y):
    """TLS via the SVD of [X Y]: smallest right singular vector v, θ = -v[:-1]/v[-1]."""
    augmented = np.column_stack((x, y))
    _, _, vt = np.linalg.svd(augmented, full_matrices=False)
    v = vt[-1]
    return -v[:-1] / v[-1]


def gtls_solve(x, y, c0):
    """GTLS via Eqs. (18)–(21): W with C0 = WᵀW, SVD of [X Y] W⁻¹, g = W⁻¹ v_min."""
    augmented = np.column_stack((x, y))
    lower = np.linalg.cholesky(c0)  # C0 = L Lᵀ
    w = lower.T  # C0 = Wᵀ W with W upper triangular
    w_inv = np.linalg.inv(w)
    _, _, vt = np.linalg.svd(augmented @ w_inv, full_matrices=False)
    g = w_inv @ vt[-1]
    return -g[:-1] / g[-1]


# --------------------------------------------------------------------------------------------
# Poles and time constants
# --------------------------------------------------------------------------------------------


def pole_to_tau(a, dt):
    return -dt / math.log(a)


def beta_poles(theta):
    """β = θ1, b1 = θ2/θ1 (Eq. 17); a1 = 1 - b1, a2 = 1 - β b1 (Eqs. 6, 12)."""
    beta = float(theta[0])
    b1 = float(theta[1]) / beta
    return {"beta": beta, "b1": b1, "a1": 1.0 - b1, "a2": 1.0 - beta * b1}


def gamma_poles(gamma):
    """a2 = γ1, a1 = -γ3/γ2 (inverse of Eq. 10)."""
    g1, g2, g3 = (float(value) for value in gamma)
    return {"gamma1": g1, "gamma2": g2, "gamma3": g3, "a1": -g3 / g2, "a2": g1}


def _with_taus(result, dt):
    result["tau1"] = pole_to_tau(result["a1"], dt)
    result["tau2"] = pole_to_tau(result["a2"], dt)
    return result


def reference_estimate(tc1, tc2, dt, method, phi=1.0):
    """Reference estimate as a dict with tau1, tau2, a1, a2 and the raw parameters."""
    if method.startswith("gamma"):
        x, y = gamma_matrices(tc1, tc2)
        if method == "gamma-ls":
            theta = ls_solve(x, y)
        elif method == "gamma-tls":
            theta = tls_solve(x, y)
        else:
            raise ValueError(method)
        return _with_taus(gamma_poles(theta), dt)
    x, y = beta_matrices(tc1, tc2)
    if method == "beta-ls":
        theta = ls_solve(x, y)
    elif method == "beta-tls":
        theta = tls_solve(x, y)
    elif method == "beta-gtls":
        theta = gtls_solve(x, y, c0_matrix(phi))
    else:
        raise ValueError(method)
    return _with_taus(beta_poles(theta), dt)


def true_params(tau1, tau2, dt):
    """The exact raw parameters of Eqs. (5), (6), (10), (12)."""
    a1 = math.exp(-dt / tau1)
    a2 = math.exp(-dt / tau2)
    b1 = 1.0 - a1
    b2 = 1.0 - a2
    return {
        "a1": a1,
        "a2": a2,
        "b1": b1,
        "beta": b2 / b1,
        "gamma1": a2,
        "gamma2": b2 / b1,
        "gamma3": -a1 * b2 / b1,
    }


# --------------------------------------------------------------------------------------------
# TDR-Kee, plain loops
# --------------------------------------------------------------------------------------------


def tdr_kee_reference(tc1, tc2, dt, alpha, smooth_samples=11, polyorder=3):
    """Median over consecutive non-overlapping windows of
    τ2 = -Σ(T1-T2)(αD1-D2) / Σ(αD1-D2)², with Savitzky–Golay smoothing and derivatives.

    Returns (tau1, tau2, per-window tau2 list).
    """
    tc1 = np.asarray(tc1, dtype=np.float64)
    tc2 = np.asarray(tc2, dtype=np.float64)
    n = tc1.size
    t1 = savgol_filter(tc1, smooth_samples, polyorder)
    t2 = savgol_filter(tc2, smooth_samples, polyorder)
    d1 = savgol_filter(tc1, smooth_samples, polyorder, deriv=1, delta=dt)
    d2 = savgol_filter(tc2, smooth_samples, polyorder, deriv=1, delta=dt)
    window = min(max(50, n // 10), n)
    per_window = []
    start = 0
    while start + window <= n:
        numerator = 0.0
        denominator = 0.0
        for k in range(start, start + window):
            combo = alpha * float(d1[k]) - float(d2[k])
            numerator += (float(t1[k]) - float(t2[k])) * combo
            denominator += combo * combo
        if denominator > 0.0:
            per_window.append(-numerator / denominator)
        start += window
    values = sorted(per_window)
    middle = len(values) // 2
    tau2 = values[middle] if len(values) % 2 else 0.5 * (values[middle - 1] + values[middle])
    return alpha * tau2, tau2, per_window
