"""The causal Kalman filter of the stream, and how its signal model is fitted off the stream.

Fitting the filter's signal model takes from a tenth of a second (a random walk) to seconds
('auto', five models); the stream must not wait for it. So a filter is *built* as a job
(:func:`build_filter`, run by a :class:`~tcomp_core.workers.JobRunner`: a worker process in the
node, inline in ``tcomp process``): the signal model fitted (or, when only τ moved, the last
one retuned), its time-varying start computed, and the filter run through the newest pairs
(*primed*). When the build lands, :meth:`KalmanReconstructor.use` catches it up through the
pairs that came meanwhile and it takes over from the next pair: no pair is published twice or
skipped, and the filter switches warm.

:class:`FilterPolicy` decides when a build is needed: the first once τ is accepted and the
window's gap-free stretch holds a window (up to :data:`~.config.FUSION_FIT_SAMPLES`), then a
refit as the stretch it was fitted on doubles (or fills the window: after a gap) or τ moves by
:data:`~.config.FUSION_REFIT_CHANGE`,
a retune of the same model when τ moves by :data:`FUSION_RETUNE_CHANGE`. A stream in a worker
first compares the quick models (a fraction of a second), then all.

The compensator holds the pairs until the first filter lands (as it holds them until the first
τ: at most one window) so that they are published with it. Should the hold outgrow the window
(a worker that is slow to start), the reconstructor publishes an *interim* filter meanwhile: a
random-walk model fitted on the newest :data:`INTERIM_SAMPLES` pairs, the one fit made on the
stream (tens of milliseconds, once); if even that fails, Eq. (7). When no signal model can be
fitted the filter falls back to one that can, and to Eq. (7) when none can, and ``note`` says
which.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..fusion import CausalFuser, FusionModel, SignalModelFits, fit_signal_models
from ..fusion.causal import MAX_EXACT_SAMPLES
from ..fusion.fitting import AUTO_MODELS, FIT_FAILURES, QUICK_MODELS
from .config import FUSION_FIT_SAMPLES, FUSION_REFIT_CHANGE, OnlineConfig
from .estimation import gap_free_runs
from .reconstructors import DifferenceReconstructor

__all__ = [
    "FUSION_RETUNE_CHANGE",
    "INTERIM_SAMPLES",
    "PRIME_PAIRS",
    "FilterBuild",
    "FilterPolicy",
    "FilterRequest",
    "KalmanReconstructor",
    "build_filter",
]

#: Relative move of τ1 or τ2 since the filter was built that makes the next accepted estimate
#: retune it (smaller moves change the gas by less than the estimate's own scatter).
FUSION_RETUNE_CHANGE = 0.01
#: Newest pairs a new filter runs through before it takes over, in the job: enough for its
#: time-varying start to end (:data:`~tcomp_core.fusion.causal.MAX_EXACT_SAMPLES`), so the
#: catching up on the stream is the steady-state recursion alone.
PRIME_PAIRS = MAX_EXACT_SAMPLES
#: Pairs the interim random-walk model is fitted on (a few tens of milliseconds).
INTERIM_SAMPLES = 512

_Pairs = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]


@dataclass(frozen=True)
class FilterRequest:
    """What a build of the causal filter needs (all of it pickles to a worker).

    Attributes
    ----------
    period_s : float
        Sample period, s.
    tau : (float, float)
        τ1, τ2 to build the filter for, s.
    signal_model : str
        ``'auto'`` or a model name (:data:`~tcomp_core.choices.SIGNAL_MODELS`).
    segment : ndarray, shape (n, 2), or None
        Gap-free tc1, tc2 (degrees C) to fit the signal model on; None retunes ``previous``.
    previous : FusionModel or None
        The model in use (retuned to ``tau`` when ``segment`` is None).
    prime : (ndarray, ndarray, ndarray)
        Stamps (ns), tc1, tc2 of the newest gap-free pairs to run the new filter through
        (empty: it starts fresh at the next pair).
    quick : bool
        'auto' compares :data:`~tcomp_core.fusion.fitting.QUICK_MODELS` only (a stream's
        first fit: the filter lands in a fraction of a second, the full comparison follows).
    """

    period_s: float
    tau: tuple[float, float]
    signal_model: str
    segment: NDArray[np.float64] | None
    previous: FusionModel | None
    prime: _Pairs
    quick: bool = False


@dataclass(frozen=True)
class FilterBuild:
    """A built filter, ready to take over.

    Attributes
    ----------
    fuser : CausalFuser or None
        The filter (None: no signal model could be used: Eq. (7) stays).
    note : str
        Models that could not be fitted and what was used instead ('' when nothing to say).
    primed_until_ns : int or None
        Stamp of the last pair the filter took (None: it starts fresh).
    samples : int
        Samples the signal model was fitted on (0 for a retune).
    refit : bool
        Whether the signal model was fitted (not only retuned to a new τ).
    quick : bool
        Whether 'auto' compared the quick models only (a full refit is due).
    misfit_warning : str
        How far the fitted stretch departs from the first-order model, when material ('' when
        not, and for a retune): :attr:`~tcomp_core.fusion.SignalModelFits.misfit_warning`.
    """

    fuser: CausalFuser | None
    note: str
    primed_until_ns: int | None
    samples: int
    refit: bool
    quick: bool = False
    misfit_warning: str = ""


def build_filter(request: FilterRequest) -> FilterBuild:
    """Fit (or retune) the signal model, build the causal filter and prime it (a job).

    The models are tried best first (:func:`~tcomp_core.fusion.fit_signal_models`, with the
    fallback from a named model to the others); the first whose filter exists and stays finite
    through the priming pairs is taken.
    """
    tau1, tau2 = request.tau
    if request.segment is None:
        if request.previous is None:
            raise ValueError("a retune needs the model in use")
        # The misfit measured at the fit's τ stays: a retune moves τ by little.
        candidates = [replace(request.previous, tau1=tau1, tau2=tau2)]
        fits_note, failures, refit, misfit_warning = "", {}, False, ""
    else:
        fits = _signal_model_fits(request)
        candidates = [model for model, _ in fits.ranked]
        fits_note, failures, refit = "", dict(fits.failures), True
        misfit_warning = fits.misfit_warning
    stamps, tc1, tc2 = request.prime
    for model in candidates:
        try:
            fuser = CausalFuser(model)
            if stamps.size:
                gas, _ = fuser.extend(tc1, tc2)
                if not np.all(np.isfinite(gas)):
                    raise ArithmeticError("numerically unstable on the newest pairs")
            fuser.schedule  # noqa: B018 - computed here, not on the stream
        except FIT_FAILURES as exc:
            failures[model.kind] = str(exc) or type(exc).__name__
            continue
        if refit:
            fits_note = SignalModelFits([], failures, request.signal_model).note(model.kind)
        return FilterBuild(
            fuser,
            fits_note,
            int(stamps[-1]) if stamps.size else None,
            0 if request.segment is None else request.segment.shape[0],
            refit,
            request.quick and refit,
            misfit_warning,
        )
    reasons = SignalModelFits([], failures, request.signal_model).note(None)
    return FilterBuild(
        None,
        f"no signal model could be used ({reasons}): Eq. (7)",
        None,
        0 if request.segment is None else request.segment.shape[0],
        refit,
    )


def _signal_model_fits(request: FilterRequest) -> SignalModelFits:
    """:func:`~tcomp_core.fusion.fit_signal_models` of a refit request, the last one kept.

    A stream can ask for a refit on the very stretch and τ of the last one (at its end, no new
    pairs since; a short record fitted whole), and the fit is a pure function of them: the
    last result is reused instead of fitting the same data again (a fraction of a second to
    seconds).
    """
    global _LAST_FITS
    segment = np.ascontiguousarray(request.segment, dtype=np.float64)
    key = (
        hashlib.blake2b(segment.tobytes(), digest_size=16).digest(),
        segment.shape,
        request.period_s,
        request.tau,
        request.signal_model,
        request.quick,
    )
    last = _LAST_FITS
    if last is not None and last[0] == key:
        return last[1]
    fits = fit_signal_models(
        segment[:, 0],
        segment[:, 1],
        request.period_s,
        *request.tau,
        model=request.signal_model,  # type: ignore[arg-type]
        auto_models=QUICK_MODELS if request.quick else AUTO_MODELS,
    )
    _LAST_FITS = (key, fits)
    return fits


#: The last refit's request key and its fits (:func:`_signal_model_fits`; one per process).
_LAST_FITS: tuple[tuple, SignalModelFits] | None = None


class KalmanReconstructor:
    """The causal Kalman filter of both sensors over the stream's pairs.

    Until a filter is handed over (:meth:`use`) it reconstructs by Eq. (7); the filter restarts
    after a gap.

    Parameters
    ----------
    config : OnlineConfig
        ``reconstruct_from`` and ``phi`` set the Eq. (7) fallback.
    period_s : float
        Sample period, seconds.
    tau : (float, float)
        τ1, τ2 of the Eq. (7) fallback, seconds.
    """

    def __init__(self, config: OnlineConfig, period_s: float, tau: tuple[float, float]) -> None:
        self._config = config
        self._period = period_s
        self._fallback = DifferenceReconstructor(config, period_s, tau)
        self._fuser: CausalFuser | None = None
        self._fuser_stamp: int | None = None  # stamp of the last sample the fuser took
        #: Whether the filter in use is the interim one.
        self.interim = False
        #: Samples the signal model in use was fitted on.
        self.samples = 0
        #: Whether it was fitted among the quick models only (a full refit is due).
        self.quick = False
        #: What the last build could not do and what it used instead ('' when nothing).
        self.note = ""
        #: How far the stretch the filter was fitted on departs from the first-order model,
        #: when material ('' otherwise): the filter's std holds it.
        self.misfit_warning = ""
        #: Values of the last :meth:`reconstruct` whose std was widened 2x or more because the
        #: readings disagree with the filter's model (:mod:`tcomp_core.fusion.consistency`).
        self.last_widened = 0

    def configure(self, config: OnlineConfig) -> None:
        """Take settings that keep the filter (``reconstruct_from``, ``phi``, ...)."""
        self._config = config
        fallback = self._fallback
        self._fallback = DifferenceReconstructor(config, self._period, fallback.tau, fallback.phi)

    @property
    def model(self) -> FusionModel | None:
        """The signal model in use (None while Eq. (7) is)."""
        return None if self._fuser is None else self._fuser.model

    @property
    def tau(self) -> tuple[float, float]:
        """τ1, τ2 (s) of the gas published: the filter's, or Eq. (7)'s until there is one."""
        model = self.model
        return self._fallback.tau if model is None else (model.tau1, model.tau2)

    def retune(self, tau: tuple[float, float], phi: float | None = None) -> None:
        """Use new time constants and their φ in Eq. (7) (the filter changes by :meth:`use`)."""
        self._fallback.retune(tau, phi)

    def use(self, build: FilterBuild, pairs: _Pairs, *, interim: bool = False) -> None:
        """Take a built filter over, caught up through ``pairs`` (their gas is not returned).

        Parameters
        ----------
        build : FilterBuild
            A build with ``fuser`` None keeps what is in use and only takes its note.
        pairs : (ndarray, ndarray, ndarray)
            The newest pairs taken (stamps ns, tc1, tc2), oldest first: those after the
            build's ``primed_until_ns`` are run through the new filter. When that stamp is
            not among them (a slow build), the filter restarts on their newest gap-free
            stretch.
        interim : bool
            Whether this is the interim filter (a later build replaces it).
        """
        self.note = build.note
        if build.fuser is None:
            return
        fuser = build.fuser
        stamps, tc1, tc2 = pairs
        start = 0
        if build.primed_until_ns is not None and stamps.size:
            at = int(np.searchsorted(stamps, build.primed_until_ns))
            if at < stamps.size and stamps[at] == build.primed_until_ns:
                start = at  # the stream continues from the last primed pair
            else:
                fuser.reset()
        elif build.primed_until_ns is not None:
            fuser.reset()
        self._fuser, self._fuser_stamp = fuser, build.primed_until_ns
        self.interim = interim
        if build.refit:
            self.samples = build.samples
            self.quick = build.quick
            self.misfit_warning = build.misfit_warning
        if stamps.size - start >= 2:
            steps = np.diff(stamps[start:]) * 1e-9
            self.reconstruct(
                stamps[start:],
                tc1[start:],
                tc2[start:],
                steps,
                steps <= self._config.gap_factor * self._period,
            )

    def reconstruct(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        steps_s: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Causal estimate over each contiguous step (degrees C) and its variance (°C²).

        The filter continues from the last sample it took when this run starts with it, and
        starts afresh after a gap or a lost one.
        """
        fuser = self._fuser
        self.last_widened = 0
        if fuser is None:
            return self._fallback.reconstruct(stamps, tc1, tc2, steps_s, contiguous)
        gas, std = [], []
        for start, stop in gap_free_runs(contiguous):
            begin = start
            if start == 0 and fuser.started and self._fuser_stamp == int(stamps[0]):
                begin = 1
            else:
                fuser.reset()
            estimates, deviations = fuser.extend(tc1[begin:stop], tc2[begin:stop])
            self.last_widened += fuser.consistency.last_widened
            gas.append(estimates)
            std.append(deviations)
        self._fuser_stamp = int(stamps[-1])
        return np.concatenate(gas), np.concatenate(std) ** 2


class FilterPolicy:
    """When the stream's causal filter is to be built again: the rules of the module notes."""

    @staticmethod
    def first_fit_samples(capacity: int) -> int:
        """Samples the first fit waits for: the window's, up to FUSION_FIT_SAMPLES.

        A signal model fitted on a fraction of a window reads a few periods of the gas (its
        line, its band, the noise floor) poorly: at 5 kHz a periodic model of a 10 Hz sine fitted
        on 0.05 s was 7 % off, on 0.8 s 0.2 %.
        """
        return min(capacity, FUSION_FIT_SAMPLES)

    @staticmethod
    def wanted(
        reconstructor: KalmanReconstructor, tau: tuple[float, float], stretch: int, capacity: int
    ) -> str:
        """``'refit'``, ``'retune'`` or ``''`` for a newly accepted ``tau`` (s).

        Parameters
        ----------
        reconstructor : KalmanReconstructor
        tau : (float, float)
            The accepted τ1, τ2, s.
        stretch : int
            Samples of the window's longest gap-free stretch.
        capacity : int
            Samples the window holds at most.
        """
        model = reconstructor.model
        if model is None or reconstructor.interim:
            return "refit" if stretch >= FilterPolicy.first_fit_samples(capacity) else ""
        if reconstructor.quick:
            return "refit"
        moved = max(
            abs(new / old - 1.0) for new, old in zip(tau, (model.tau1, model.tau2), strict=True)
        )
        # Refit as the stretch doubles, up to the most a fit takes: FUSION_FIT_SAMPLES or the
        # whole window. A model fitted on the short stretch after a gap is refitted once the
        # stretch reaches that most, though it cannot double: else it stayed for good (a
        # band-limited model fitted on 700 pairs of a 1 000-pair window, where the whole
        # window gives random-walk, widened the std at every corner of a ramp).
        fitted = reconstructor.samples
        most = FilterPolicy.first_fit_samples(capacity)
        grown = fitted < most and min(stretch, most) >= min(2 * fitted, most)
        if moved >= FUSION_REFIT_CHANGE or grown:
            return "refit"
        return "retune" if moved >= FUSION_RETUNE_CHANGE else ""


def interim_build(
    segment: NDArray[np.float64], period_s: float, tau: tuple[float, float]
) -> FilterBuild:
    """The interim filter: a random-walk model fitted on the newest :data:`INTERIM_SAMPLES`."""
    empty = (np.empty(0, np.int64), np.empty(0), np.empty(0))
    build = build_filter(
        FilterRequest(period_s, tau, "random-walk", segment[-INTERIM_SAMPLES:], None, empty)
    )
    return build if build.fuser is not None else replace(build, note="")


def stretch_of(segment: NDArray[np.float64]) -> NDArray[np.float64]:
    """The newest :data:`~.config.FUSION_FIT_SAMPLES` of a gap-free stretch (n, 2)."""
    return segment[-FUSION_FIT_SAMPLES:]


def finite_tau(tau: tuple[float, float] | None) -> bool:
    """Whether ``tau`` holds two finite positive time constants."""
    return tau is not None and all(math.isfinite(t) and t > 0.0 for t in tau)
