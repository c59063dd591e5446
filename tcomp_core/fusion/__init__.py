"""Fused gas temperature reconstruction: a Kalman filter and RTS smoother on both sensors.

The paper inverts each thermocouple (Eq. 7), averages the two reconstructions and low-passes the
result with a post-filter whose bandwidth the user has to choose. Here the gas temperature is a
stochastic state of a linear Gaussian state-space model, both sensors observe it, and every
setting comes from the data:

    s_k = [x_{k-1}, T_1(k), T_2(k)],           g_{k-1} = c_s · x_{k-1},
    x_k = F_s x_{k-1} + w_k,                   w_k ~ N(0, Q_s),
    T_i(k+1) = a_i T_i(k) + (1 - a_i) g_k,     a_i = exp(-dt/τ_i)   (Eqs. 4–6, exact ZOH),
    y_i(k) = T_i(k) + v_i(k),                  v_i ~ N(0, σ_i²),

with g_k the gas temperature held over ``[t_k, t_{k+1})`` and x the state of a signal model
(:data:`MODELS`), each a continuous-time linear system driven by white noise and discretised
exactly (Van Loan):

``random-walk``
    ``dg/dt = w``, intensity q in °C²/s. Suits steps and jumps.
``integrated-random-walk``
    ``d²g/dt² = w``, q in °C²/s³. Suits ramps and smooth signals.
``band-limited``
    a random-walk level (``level_q``, °C²/s) plus white noise through a Butterworth low-pass
    of order ``order`` (2 or 4, the likelihood chooses) with cut-off ``freq_hz``: flat up to
    the cut-off, falling as f^(-2·order) above it. q (°C²/s) is the intensity of the noise
    driving the highest derivative, scaled to °C (:func:`butterworth_dynamics`). Suits
    broadband signals with a band edge.
``periodic``
    a random-walk level plus an undamped resonator at the frequency ``freq_hz`` of the
    spectrum's strongest line, driven by white noise of intensity q in °C²/s: a sinusoid whose
    amplitude and phase wander. Suits periodic signals. (A damped resonator would make the
    model expect the amplitude to decay between the rare corrections a weak drive allows.)

``autoregressive``
    the gas's sample-to-sample change d_k as an autoregression of order p (8 to 32, Akaike
    chooses) whose coefficients come from the gas spectrum seen in the cross-spectrum of the
    two readings (Yule–Walker; the independent noises do not bias it) and whose innovation
    variance q (°C² per sample) is fitted by maximum likelihood: a spectrum of any shape, e.g.
    the 1/f-like spectrum of a broadband multisine with its band edge, or of exhaust pulses.
    Bins where the cross-spectrum does not stand above its noise count as empty, and a floor
    six decades below the peak keeps the roots off the unit circle. Discrete, so not
    discretised.

Hyper-parameters are chosen by maximising the likelihood of the Kalman innovations
(:mod:`scipy.optimize` on their logarithms), and the model by that likelihood less its number
of hyper-parameters (Akaike). The noise levels σ_i come from the model
(:func:`tcomp_core.noise.model_noise`: the spectra less the gas signal both share) unless
given.

For a time-invariant model the Kalman gain converges to a constant, found once from the
discrete algebraic Riccati equation; filter and Rauch–Tung–Striebel smoother are then linear
recursions, run in a Schur basis as first-order :func:`scipy.signal.lfilter` calls (no Python
loop over samples). Offline, the unknown initial state is estimated by generalised least squares
from the innovations (a diffuse prior) and its uncertainty is added to the reported standard
deviation. The causal filter starts from a diffuse prior with the exact time-varying Kalman
recursion (a loop over samples) and switches to the steady-state gain once its gain has
converged, or after :data:`MAX_EXACT_SAMPLES` samples.

Output convention: element k of every gas series is the gas temperature held over
``[t_k, t_{k+1})``, as in :func:`tcomp_core.reconstruct.reconstruct`. The causal filter emits it
when sample k+1 arrives (the one-sample latency of Eq. 7); the last element, which no sample
observes, is a one-step prediction with the wider standard deviation that goes with it.

Modules: :mod:`.signal_model` (signal models, state-space model), :mod:`.recursion` (linear
recursions without a loop over samples), :mod:`.kalman` (steady-state filter, likelihood),
:mod:`.smoother` (RTS smoother), :mod:`.fitting` (maximum likelihood), :mod:`.causal` (streaming
filter), :mod:`.record` (:func:`fuse`).
"""

from __future__ import annotations

from .causal import CausalFuser
from .fitting import SignalModelFits, first_order_adequacy, fit_fusion_model, fit_signal_models
from .kalman import SteadyState, steady_state
from .record import FusionResult, fuse
from .recursion import linear_recursion
from .signal_model import (
    MODELS,
    FusionModel,
    ModelChoice,
    ModelKind,
    StateSpace,
    butterworth_dynamics,
)

__all__ = [
    "MODELS",
    "CausalFuser",
    "FusionModel",
    "FusionResult",
    "ModelChoice",
    "ModelKind",
    "SignalModelFits",
    "StateSpace",
    "SteadyState",
    "butterworth_dynamics",
    "first_order_adequacy",
    "fit_fusion_model",
    "fit_signal_models",
    "fuse",
    "linear_recursion",
    "steady_state",
]
