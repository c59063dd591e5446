"""Conduction along the legs to the supports (fin theory).

A junction between two legs of length L that end on supports is a fin. The wire (diameter d,
heat capacity ρc, conductivity k_w) in a cross flow of coefficient h obeys

    τ ∂T/∂t = (1/m²) ∂²T/∂x² + T_g − T,    τ = ρcd/(4h),    m² = 4h/(k_w d),

and with the support temperature following the gas through a first-order lag of time constant
τp the junction (the legs' midpoint) reads

    G(s) = (1 − S(s)) / (1 + τ s) + S(s) / (1 + τp s),    S(s) = sech(mL √(1 + τ s)),

unity DC gain: the legs pull the junction towards the supports by S, which fades with
frequency as the wire's own lag takes over. Factored as G = M / (1 + τ s),

    M(s) = 1 − (τp − τ) s S(s) / (1 + τp s),

the base first-order lag is kept and conduction is the filter M, minimum phase for supports
slower than the wire (τp ≥ τ/2: on the imaginary axis the subtracted term's modulus is below
|1 − τ/τp| sech(mL) < 1, so M has no zero in the right half plane) and hence stably invertible
(:func:`fin_filter`). S is the Weierstrass product of cosh,

    S(s) = Π_n 1 / ((1 + a_n)(1 + τ_n s)),    a_n = 4 (mL)² / ((2n − 1)² π²),
    τ_n = τ a_n / (1 + a_n),

of which the first :data:`FIN_TERMS` factors are kept as they are and the rest as one lag of
their summed time constant (first moment) and their DC gain: M is within 0.5 % of exact up
to ωτ = 2π and 1 % up to ωτ = 60 (``test/test_effects_chain_fast_paths.py``).

Two wires of one material (diffusivity α = k_w/ρc) on alike supports (one L) share
m² τ = ρc/k_w, so

    (mL_i)² τ_i = L²/α = τ_leg    for both,

one parameter, the legs' diffusion time, whatever the Nusselt law. This is what a lumped model
(G = [1 + κ/(1 + τp s)]/(1 + κ + τ s), one κ per wire) cannot express: its two κ and the τ
form a family that explains the two signals equally well and had to be fixed by a prior; with
fin physics the family is gone. The lumped model's steady conductance ratio is reported for
comparison, κ = 1/(cosh(mL) − 1) (:func:`fin_kappa`).

The slow mode remembers for several τp: a record that does not start at rest starts with the
supports off their equilibrium. Their initial excess, seen by sensor i as ``mode_i`` e^(−t/τp)
degrees C on its reading, is fitted per sensor, so a window cut from a running record fits as
well as one that starts at rest.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from ..io.screening import VALID_RANGE_C
from .base import Effect, FitContext, OutputEvidence, ParamSpec

__all__ = [
    "CONSTANT_SUPPORT_LAG_S",
    "FIN_TERMS",
    "Conduction",
    "fin_filter",
    "fin_kappa",
    "fin_length",
    "fin_sech",
]

#: Factors of the Weierstrass product of sech kept as they are (the rest make one lag).
FIN_TERMS = 6
#: Search range of the fin length of the slower wire, mL: 0.4 (conduction dominates: κ ≈ 12)
#: to 7 (the supports pull by sech(7) ≈ 0.2 %: no conduction).
FIN_ML_RANGE = (0.4, 7.0)
#: Largest steady conductance ratio κ of a plausible fit (mL = 0.4 at the fit's own τ).
MAX_KAPPA = 1.0 / (math.cosh(FIN_ML_RANGE[0]) - 1.0)
#: Largest initial excess of the supports over their equilibrium, degrees C: the width of the
#: range any thermocouple reading may take (:data:`tcomp_core.io.screening.VALID_RANGE_C`).
MAX_SUPPORT_EXCESS_C = VALID_RANGE_C[1] - VALID_RANGE_C[0]
#: The simulator's fin legs: mL of the slower wire (its supports pull it by sech(1.7) = 35 %
#: at DC) and the supports' lag, s.
SIMULATED_FIN_ML = 1.7
SIMULATED_SUPPORT_LAG_S = 1.0
#: The supports' lag in the constant-supports form (:attr:`Conduction.alternative_forms`), s:
#: ten days, beyond any record, so that over the record the supports hold the temperature
#: their initial excess (``mode_i``) gives them.
CONSTANT_SUPPORT_LAG_S = 1e6
#: The simulator's lumped prong: the slower wire's conductance to its prong over its convective
#: conductance (the fast band reads 1/(1 + 0.4) = 71 % of the gas's swing).
SIMULATED_PRONG_KAPPA = 0.4


def fin_kappa(fin_ml: float) -> float:
    """Steady conductance ratio κ = 1/(cosh(mL) − 1) of a junction between two fins."""
    half = 0.5 * fin_ml
    if half > 350.0:  # sinh overflows; κ is 0 to double precision long before
        return 0.0
    return 1.0 / (2.0 * math.sinh(half) ** 2)


def fin_sech(fin_ml: float) -> float:
    """sech(mL), the supports' steady share of the junction; 0 where cosh overflows.

    A search can pass a very short wire τ, and mL = √(τ_leg/τ) grows without bound there
    (a campaign draw stopped on ``math range error``).
    """
    return 0.0 if fin_ml > 700.0 else 1.0 / math.cosh(fin_ml)


def fin_length(kappa: float) -> float:
    """The fin length mL whose conductance ratio is ``kappa`` (:func:`fin_kappa` inverted)."""
    if kappa <= 0.0:
        return math.inf
    return 2.0 * math.asinh(math.sqrt(0.5 / kappa))


@functools.lru_cache(maxsize=256)
def fin_filter(
    tau: float, fin_ml: float, tau_p: float, terms: int = FIN_TERMS
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Zeros and poles of the fin filter M(s) (unity DC gain; M⁻¹ swaps them).

    M = 1 − N/D = (D − N)/D with D(s) = (1 + τp s) Π(1 + τ_n s)(1 + τ_tail s) and
    N(s) = sech(mL)(τp − τ) s: the poles are D's roots (real), the zeros D − N's (left half
    plane, M being minimum phase for τp ≥ τ/2; otherwise reflected there), and as D and D − N
    have the same leading coefficient, M = Π(s − zeros)/Π(s − poles).

    Parameters
    ----------
    tau : float
        The wire's convective time constant, s.
    fin_ml : float
        mL of its legs.
    tau_p : float
        Time constant of the supports' lag, s.
    terms : int
        Factors of S kept as they are.

    Returns
    -------
    zeros, poles : ndarray of complex, shape (terms + 2,) each, 1/s
    """
    # A fit designs this filter for every parameter it moves: a few numbers each, in Python
    # floats (numpy's calls cost more than their arithmetic here; the operations and their
    # order are those of the array expressions, so the results are the same to the bit).
    square = 4.0 * fin_ml**2
    tau_n = [tau * a / (1.0 + a) for a in (square / scale for scale in _fin_scales(terms))]
    # Σ over all n of τ a_n/(1 + a_n) is τ (mL/2) tanh(mL) (the first moment of sech(mL√(1+τs)));
    # the factors beyond ``terms`` make one lag of the rest.
    tail = max(tau * 0.5 * fin_ml * math.tanh(fin_ml) - sum(tau_n), 1e-12 * tau)
    lags = [tau_p, *tau_n, tail]
    coefficients = [1.0]
    for lag in lags:  # D(s) = Π(lag s + 1), highest power first
        coefficients = [
            coefficients[0] * lag,
            *(coefficients[k] * lag + coefficients[k - 1] for k in range(1, len(coefficients))),
            coefficients[-1],
        ]
    coefficients[-2] -= (tau_p - tau) * fin_sech(fin_ml)  # D − N
    zeros = _roots(coefficients).astype(np.complex128)
    # With τp < τ/2 (supports faster than the wire: no physical rig, but a search can pass
    # there) M is not minimum phase; zeros reflected into the left half plane keep |M| and a
    # stable inverse.
    zeros = np.where(zeros.real > 0.0, -zeros.conj(), zeros)
    return zeros, np.array([-1.0 / lag for lag in lags], dtype=np.complex128)


@functools.lru_cache(maxsize=8)
def _fin_scales(terms: int) -> tuple[float, ...]:
    """(2n − 1)² π² for n = 1 .. ``terms``: a_n = 4 (mL)² over these."""
    n = np.arange(1, terms + 1)
    return tuple(((2 * n - 1) ** 2 * math.pi**2).tolist())


def _roots(coefficients: list[float]) -> NDArray[np.inexact]:
    """``np.roots`` of a polynomial, highest power first.

    The eigenvalues of the companion matrix ``np.roots`` builds, without its trimming of
    leading and trailing zeros (half its time on a polynomial of degree 8) when neither end
    is 0; otherwise ``np.roots`` itself.
    """
    if len(coefficients) < 2 or coefficients[0] == 0.0 or coefficients[-1] == 0.0:
        return np.roots(coefficients)
    companion = np.eye(len(coefficients) - 1, k=-1)
    lead = coefficients[0]
    companion[0] = [-value / lead for value in coefficients[1:]]
    return np.linalg.eigvals(companion)


class Conduction(Effect):
    """τ_leg (s), τp (s) and the supports' initial excess ``mode1``, ``mode2`` (degrees C).

    Plausible (:meth:`implausible`) when each wire's steady conductance ratio to its supports,
    κ_i = :func:`fin_kappa` (√(τ_leg/τ_i)) at the fit's own τ_i, is at most
    :data:`MAX_KAPPA`: the edge of the search range of mL (0.4), where the supports take
    over 90 % of the junction's steady heat balance. A junction whose conductance to its
    supports is tens or hundreds of times its convective conductance reads the supports, not
    the gas: it is not a thermocouple in a flow, and such a fit has only traded τ for legs.
    And when the supports' initial excess a reading shows, ``mode_i``, is more than their
    share of the junction, sech(mL_i), can pass of :data:`MAX_SUPPORT_EXCESS_C`: supports
    that far from equilibrium lie outside any thermocouple's range, and the fit has used the
    transient to absorb a start-up mismatch (a noise-ratio record at 0.5 kHz was read as
    conduction with mL1 = 9.8, mode1 = 103 degC where sech(9.8) lets through 0.25 degC at
    most; compensated, its gas went 1.3 → 9.3 % off).

    How far τ may move from the first-order estimate is one-sided. Supports that lag the gas
    add a slow path the first-order fit absorbs into τ, which can then be many times the
    wire's own (it tends to τp as the supports take over): τ may fall below it without limit
    (:attr:`max_tau_fall`). Supports at a steady temperature make the junction answer
    faster, τ/(1 + κ), so the first-order τ is at most 1 + :data:`MAX_KAPPA` times too short:
    τ may rise above it by that factor at most (:attr:`max_tau_factor`).
    """

    name = "conduction"
    max_tau_factor = 1.0 + MAX_KAPPA
    max_tau_fall = math.inf
    #: Supports held at a constant temperature (a mount cooled or heated apart from the gas)
    #: instead of lagging it: the form of the literature's steady fin analyses, and the
    #: limit of this one as τp outlasts the record. The fit's τp is bounded by the record
    #: (a third of it), so supports that lag longer than it can show end on that bound,
    #: where the fit's form, not the data, decides what the slow path does to the gas: on
    #: the detailed simulator's supports lagging 1–4 s behind a 4 s record (campaign draw
    #: 2887, τp on its 1.33 s bound) the fitted correction made the gas 10.1 → 20.4 % off.
    #: What this form changes against the fit's joins the gas's band.
    alternative_forms = ({"conduction_constant_supports": 1.0},)

    simulation_forms = ("fin legs", "lumped prong")

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """``fin legs``: tau_leg, tau_p (s). ``lumped prong``: kappa1, kappa2, tau_p.

        The prong form is the lumped model, G = [1 + κ/(1 + τp s)]/(1 + κ + τ s): the junction
        exchanges heat with a prong that lags the gas. Its conductance to the prong (∝ d²) over
        the convective one (h d² with h ∝ d^-½) grows as d^½ ∝ τ^⅓, so κi ∝ τi^⅓.
        """
        slow = max(tau1, tau2)
        if form == "lumped prong":
            return {
                "kappa1": SIMULATED_PRONG_KAPPA * (tau1 / slow) ** (1.0 / 3.0),
                "kappa2": SIMULATED_PRONG_KAPPA * (tau2 / slow) ** (1.0 / 3.0),
                "tau_p": SIMULATED_SUPPORT_LAG_S,
            }
        return {"tau_leg": SIMULATED_FIN_ML**2 * slow, "tau_p": SIMULATED_SUPPORT_LAG_S}

    def output_handling(self, fit: OutputEvidence) -> tuple[str, str]:
        return (
            "compensated",
            "fin legs: the common leg time L^2/alpha set by the free-run error, not a prior",
        )

    summary = "conduction along the legs to supports that lag the gas (tau_leg, tau_p)"
    # Where the fin model is not exact (a junction bead; little slow excitation) the
    # cross-relation criterion trades a misfit for noise gain along τ ∝ 1/mL², towards legs
    # far shorter than real ones and τ tens of percent high; the free-run error does not.
    output_error_params = ("tau_leg",)
    output_error_coupled = True  # τ and the supports' lag move with the legs' length

    def implausible(self, params: Mapping[str, float]) -> str:
        if "tau_leg" not in params:
            return ""
        for index in (1, 2):
            tau = params.get(f"tau{index}", math.nan)
            if not tau > 0.0:
                continue
            fin_ml = math.sqrt(params["tau_leg"] / tau)
            kappa = fin_kappa(fin_ml)
            if kappa > MAX_KAPPA:
                return (
                    f"conduction: wire {index}'s conductance to its supports is {kappa:.3g}x "
                    f"its convective conductance (at most {MAX_KAPPA:.3g}x)"
                )
            share = fin_sech(fin_ml)
            mode = abs(params.get(f"mode{index}", 0.0))
            if mode > share * MAX_SUPPORT_EXCESS_C:
                return (
                    f"conduction: wire {index}'s reading starts {mode:.3g} degC off through "
                    f"its supports' share sech(mL) = {share:.3g}, so the supports would start "
                    f"{mode / share if share > 0.0 else math.inf:.3g} degC off their "
                    f"equilibrium (at most {MAX_SUPPORT_EXCESS_C:.4g} degC)"
                )
        return ""

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        slowest = max(context.duration_s / 3.0, 4.0 * context.tau_scale_s)
        span = 10.0 * context.level_std_c + 10.0
        low, high = FIN_ML_RANGE
        return (
            ParamSpec(
                name="tau_leg",
                unit="s",
                lower=low**2 * context.tau_scale_s,
                upper=high**2 * context.tau_scale_s,
                description="diffusion time of the legs L^2/alpha, common to both wires",
            ),
            ParamSpec(
                name="tau_p",
                unit="s",
                lower=1.5 * context.tau_scale_s,
                upper=slowest,
                description="time constant of the supports' lag",
                physical=False,  # supports may lag longer than the record can show
            ),
            ParamSpec(
                name="mode1",
                unit="degC",
                lower=-span,
                upper=span,
                description="initial excess of the supports seen by tc1",
                physical=False,
            ),
            ParamSpec(
                name="mode2",
                unit="degC",
                lower=-span,
                upper=span,
                description="initial excess of the supports seen by tc2",
                physical=False,
            ),
        )

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        leg, support = self.specs(context)[:2]
        slow_tau = max(params["tau1"], params["tau2"])
        if "tau_leg" in params:  # given (the output-error search): the supports' lag only
            legs, supports = [params["tau_leg"]], 2
        else:
            legs = [
                min(max(ml**2 * slow_tau, 1.01 * leg.lower), 0.99 * leg.upper) for ml in (1.2, 2.5)
            ]
            supports = 4
        return [
            {"tau_leg": tau_leg, "tau_p": float(tau_p), "mode1": 0.0, "mode2": 0.0}
            for tau_p in np.geomspace(support.lower * 1.5, support.upper / 1.5, supports)
            for tau_leg in legs
        ]

    @staticmethod
    def fin_ml(sensor: int, params: Mapping[str, float]) -> float:
        """The fin length mL of the legs of ``sensor``: √(τ_leg / τ_i)."""
        return math.sqrt(params["tau_leg"] / params[f"tau{sensor}"])

    def identifiability(self, params: Mapping[str, float]) -> str:
        ml1, ml2 = self.fin_ml(1, params), self.fin_ml(2, params)
        return (
            "conduction: the wires are taken as one material on alike supports, so one leg "
            f"diffusion time L^2/alpha = {params['tau_leg']:.3g} s sets both (mL1 = "
            f"{ml1:.3g}, mL2 = {ml2:.3g}; steady conductance ratios kappa1 = "
            f"{fin_kappa(ml1):.3g}, kappa2 = {fin_kappa(ml2):.3g}); wires of different "
            "materials or leg lengths are outside this model"
        )

    def conduction(self, sensor: int, params: Mapping[str, float]) -> tuple[float, float, float]:
        tau_p = (
            CONSTANT_SUPPORT_LAG_S
            if params.get("conduction_constant_supports", 0.0)
            else params["tau_p"]
        )
        return self.fin_ml(sensor, params), tau_p, params[f"mode{sensor}"]
