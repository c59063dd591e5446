"""``tcomp reconstruct``: the gas temperature by Eq. (7) or a Kalman smoother (or filter)."""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from ..choices import BATCH_RECONSTRUCTIONS, COMBINATIONS, MODELS
from ..errors import TcompError, TcompWarning
from .common import (
    Verbs,
    add_data_arguments,
    add_estimator_arguments,
    add_force_argument,
    add_output_argument,
    compensate_effects,
    estimate_with,
    positive_float,
    read_data,
)

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from ..compensation import OutputModel
    from ..io import Record
    from ..reconstruct import Reconstruction

__all__ = ["NOISE_GAIN_WARNING", "add_parser", "run"]

#: Eq. (7) without a post-filter is warned about from this noise gain on: 16 at the paper's
#: conditions (τ1 = 12 samples), 170 at 5 kHz and 670 at 20 kHz for the same sensors.
NOISE_GAIN_WARNING = 50.0


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``reconstruct`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "reconstruct",
        help="reconstruct the gas temperature (Kalman smoother by default, or Eq. 7)",
        description="Estimate tau1, tau2 (or take them as given) and reconstruct the gas "
        "temperature from both thermocouples: by default by a Kalman smoother of both sensors "
        "whose gas temperature model and settings are fitted to the data by maximum likelihood "
        "(or its causal filter); with --reconstruction difference through the paper's "
        "difference equation (Eq. 7).",
    )
    add_data_arguments(parser)
    add_estimator_arguments(parser)
    add_output_argument(parser, "*.csv or an MCAP bag directory")
    parser.add_argument("--tau1", type=positive_float, help="use this tau1 (s), skip estimation")
    parser.add_argument("--tau2", type=positive_float, help="use this tau2 (s), skip estimation")
    parser.add_argument(
        "--postfilter-hz", type=positive_float, help="5th-order zero-phase post-filter, Hz"
    )
    parser.add_argument(
        "--combine",
        choices=COMBINATIONS,
        default="inverse-variance",
        help="how the two reconstructions are combined (default inverse-variance)",
    )
    parser.add_argument(
        "--reconstruction",
        choices=BATCH_RECONSTRUCTIONS,
        default="kalman",
        help="kalman (default): the RTS smoother of both sensors, the best gas offline; "
        "kalman-causal: the forward filter alone, as the node runs it; difference: the "
        "paper's Eq. (7). When no signal model can be fitted the Kalman reconstructions fall "
        "back to one that can, and to Eq. (7) when none can, and say so",
    )
    parser.add_argument(
        "--signal-model",
        choices=["auto", *MODELS],
        default="auto",
        help="gas temperature model of the Kalman reconstructions (default auto: the most "
        "likely, penalised by its number of settings)",
    )
    parser.add_argument(
        "--effects",
        default="none",
        help="compensate with physics beyond the first-order model: 'auto' (the diagnosis's "
        "final model), a comma-separated list of effects to fit, a diagnosis saved by 'tcomp "
        "diagnose --json' (FILE.json: the effects its final model found, fitted here without "
        "diagnosing again), or 'none' (default); tau1, tau2 are then fitted with the effects",
    )
    parser.add_argument(
        "--json",
        type=Path,
        metavar="FILE",
        help="with --effects: write the output model (how each effect is treated, its "
        "parameters and errors) and the errors against the ref signal as JSON",
    )
    parser.add_argument("--png", type=Path, help="also plot the reconstruction to this PNG")
    add_force_argument(parser, "overwrite an existing output")
    parser.set_defaults(handler=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Estimate τ1, τ2 unless given, reconstruct, write ``--output`` (and ``--png``).

    Raises
    ------
    TcompError
        If only one of ``--tau1``/``--tau2`` is given, or a Kalman reconstruction is asked
        for with options of the difference equation.
    """
    from ..compensation import parse_compensate_effects
    from ..lines import line_free_pair

    record = read_data(args)
    if (args.tau1 is None) != (args.tau2 is None):
        raise TcompError("give both --tau1 and --tau2, or neither to estimate them")
    effects = parse_compensate_effects(compensate_effects(args.effects))
    if args.json is not None and effects == ():
        raise TcompError("--json describes the output model of --effects: give --effects too")
    if effects != ():
        if args.tau1 is not None:
            raise TcompError("--effects fits tau1 and tau2 with the effects: drop --tau1/--tau2")
        return _run_compensated(record, args, effects)
    readings = record.tc1, record.tc2
    tau_log_se = None  # τ given: its uncertainty is the user's to know
    if args.tau1 is None:
        result = estimate_with(record, args, args.method)
        tau1, tau2 = result.tau1, result.tau2
        tau_log_se = result.tau_log_se()
        print(f"{args.method}: tau1 = {tau1:.6f} s, tau2 = {tau2:.6f} s")
        if result.lines:
            # The gas never carried the line: take it off the sensor that did, not the gas.
            readings = line_free_pair(*readings, record.dt, result.lines, (tau1, tau2))
    else:
        tau1, tau2 = args.tau1, args.tau2
    if args.reconstruction != "difference":
        return _run_kalman(record, args, (tau1, tau2), readings, tau_log_se)
    return _run_difference(record, args, tau1, tau2, readings)


def _run_difference(
    record: Record,
    args: argparse.Namespace,
    tau1: float,
    tau2: float,
    readings: tuple[NDArray[np.float64], NDArray[np.float64]],
) -> int:
    """``reconstruct --reconstruction difference``: Eq. (7) and the combination.

    Without a post-filter the gas's variance (the readings' white noise through Eq. 7,
    :func:`~tcomp_core.reconstruct.gas_noise_variance`) is written with it. ``readings`` are
    tc1 and tc2 as reconstructed from (without the lines only one sensor carried).
    """
    import numpy as np

    from ..estimators.mleiv import phi_from_data
    from ..fusion.adequacy import first_order_misfit
    from ..metrics import reconstruction_error_percent
    from ..noise import model_noise
    from ..reconstruct import gas_noise_variance, noise_gain, reconstruct

    recon = reconstruct(
        *readings,
        record.dt,
        tau1,
        tau2,
        phi=(
            args.phi
            if args.phi is not None
            else phi_from_data(*readings, record.dt, taus=(tau1, tau2), unmeasurable=1.0)
        ),
        combine=args.combine,
        postfilter_hz=args.postfilter_hz,
        time=record.time,
    )
    count = recon.gas.size
    poles = math.exp(-record.dt / tau1), math.exp(-record.dt / tau2)
    variance = None
    if args.postfilter_hz is None:  # white noise through Eq. 7 alone: its variance is known
        noise1, noise2 = model_noise(*readings, record.dt, tau1, tau2)
        spread = gas_noise_variance(*poles, recon.weight1, noise1.sigma, noise2.sigma)
        # What the first-order model does not explain, as the smoother's std holds it.
        misfit = first_order_misfit(*readings, record.dt, tau1, tau2, noise1.sigma, noise2.sigma)
        variance = np.full(count, spread + misfit.excess_c**2)
        gas_std = math.sqrt(max(float(np.nanvar(recon.gas)) - spread, 0.0))
        if misfit.material(gas_std):
            _warn_misfit(
                record, misfit.describe(gas_std), "tcomp diagnose names the missing physics"
            )
    written, ref = _write_gas(args, record, recon.gas, variance)
    print(
        f"wrote {written}: gas temperature at {count} of {record.tc1.size} samples "
        f"(the last sample has no successor to reconstruct from), weight of tc1 "
        f"{recon.weight1:.3f}"
    )
    gain = noise_gain(*poles, recon.weight1)
    if args.postfilter_hz is None and gain >= NOISE_GAIN_WARNING:
        warnings.warn(
            f"{record.source}: Eq. (7) multiplies the readings' noise {gain:.0f} times at this "
            f"rate (tau1 = {tau1 / record.dt:.0f} samples): the gas scatters far beyond what "
            "the readings allow; --postfilter-hz, or the default --reconstruction kalman, "
            "gives the gas without it",
            TcompWarning,
            stacklevel=1,
        )
    if ref is not None:
        for label, values in (("tc1", recon.gas1), ("tc2", recon.gas2), ("combined", recon.gas)):
            error = reconstruction_error_percent(ref, values)
            print(f"e_Tg ({label}) = {error:.2f} % against the ref signal")
    if args.png:
        _plot(args, record, recon.gas, ref, variance)
    return 0


def _run_kalman(
    record: Record,
    args: argparse.Namespace,
    taus: tuple[float, float],
    readings: tuple[NDArray[np.float64], NDArray[np.float64]],
    tau_log_se: tuple[float, float] | None,
) -> int:
    """``reconstruct --reconstruction kalman[-causal]``; Eq. (7) when no model can be used.

    ``readings`` as for :func:`_run_difference`; ``tau_log_se`` the standard errors of log τ
    of the estimate (None when τ was given, or its method gives none): what τ's uncertainty
    adds to the gas is then added to its std (:mod:`tcomp_core.fusion.tau_spread`).
    """
    import numpy as np

    from ..errors import EstimationError
    from ..fusion import fuse
    from ..fusion.tau_spread import with_tau_spread
    from ..metrics import reconstruction_error_percent

    _check_difference_options(args)
    causal = args.reconstruction == "kalman-causal"
    try:
        fused = fuse(*readings, record.dt, *taus, model=args.signal_model, causal=causal)
    except EstimationError as exc:
        print(f"tcomp reconstruct: warning: {exc}; the gas is Eq. (7)'s", file=sys.stderr)
        return _run_difference(record, args, *taus, readings)
    if fused.note:
        print(f"tcomp reconstruct: note: {fused.note}", file=sys.stderr)
    _warn_misfit(record, fused.misfit_warning, "tcomp diagnose names the missing physics")
    if tau_log_se is not None:
        fused = with_tau_spread(fused, *readings, tau_log_se)
        print(
            f"the std holds tau's uncertainty (sigma {100 * tau_log_se[0]:.3g} % and "
            f"{100 * tau_log_se[1]:.3g} % of tau1, tau2)"
        )
    model = fused.model
    settings = f"q = {model.q:.4g}"
    if model.kind in ("band-limited", "periodic"):
        settings += f", {model.freq_hz:.4g} Hz, level q = {model.level_q:.4g}"
    print(
        f"{args.reconstruction}: signal model {model.kind} ({settings}), noise sigma1 = "
        f"{model.sigma1:.4g}, sigma2 = {model.sigma2:.4g} degC, log-likelihood "
        f"{fused.log_likelihood:.1f}; median std of the estimate {np.median(fused.std):.4g} degC"
    )
    # The last element is a prediction no sample observes: leave it out as Eq. (7) does.
    count = record.tc1.size - 1
    gas = fused.gas[:count]
    written, ref = _write_gas(args, record, gas, fused.std[:count] ** 2)
    print(f"wrote {written}: gas temperature at {count} of {record.tc1.size} samples")
    if ref is not None:
        error = reconstruction_error_percent(ref, gas)
        print(f"e_Tg ({args.reconstruction}) = {error:.2f} % against the ref signal")
    if args.png:
        _plot(args, record, gas, ref, fused.std[:count] ** 2)
    return 0


def _warn_misfit(record: Record, warning: str, remedy: str) -> None:
    """Warn that the readings depart from the model the gas is reconstructed with."""
    if warning:
        warnings.warn(
            f"{record.source}: {warning}. {remedy}, and --effects auto compensates what it finds",
            TcompWarning,
            stacklevel=1,
        )


def _check_difference_options(args: argparse.Namespace) -> None:
    """Refuse the options of Eq. (7) with a Kalman reconstruction."""
    if args.postfilter_hz is not None or args.combine != "inverse-variance":
        raise TcompError(
            "--postfilter-hz and --combine apply to --reconstruction difference (Eq. 7); the "
            f"Kalman {'filter' if args.reconstruction == 'kalman-causal' else 'smoother'} "
            "needs neither"
        )


def _run_compensated(
    record: Record, args: argparse.Namespace, effects: tuple[str, ...] | None
) -> int:
    """``reconstruct --effects``: the output model fitted, the readings made first order."""
    import numpy as np

    from ..compensation import compensate, equivalent_readings, fit_output_model, level_shift_c
    from ..estimators.mleiv import phi_from_data
    from ..reconstruct import reconstruct

    model = fit_output_model(record, effects)
    print("\n".join(model.describe()))
    print(
        f"tau1 = {model.tau1:.6f} s, tau2 = {model.tau2:.6f} s; held-out model error "
        f"{model.error_pct:.3g} % (first order {model.base_error_pct:.3g} %)"
    )
    count = record.tc1.size - 1
    if args.reconstruction == "difference":
        tc1, tc2 = equivalent_readings(model, record.time, record.tc1, record.tc2, record.dt)
        phi = (
            args.phi
            if args.phi is not None
            else phi_from_data(tc1, tc2, record.dt, unmeasurable=1.0)
        )

        def eq7(first: NDArray[np.float64], second: NDArray[np.float64]) -> Reconstruction:
            return reconstruct(
                first,
                second,
                record.dt,
                model.tau1,
                model.tau2,
                phi=phi,
                combine=args.combine,
                postfilter_hz=args.postfilter_hz,
                time=record.time,
            )

        recon = eq7(tc1, tc2)
        shift = level_shift_c(
            model,
            recon.gas,
            lambda first, second: eq7(first, second).gas,
            record.time,
            record.tc1,
            record.tc2,
            record.dt,
        )
        gas = recon.gas + shift
    else:
        _check_difference_options(args)
        causal = args.reconstruction == "kalman-causal"
        result = compensate(
            model,
            record.time,
            record.tc1,
            record.tc2,
            record.dt,
            signal_model=args.signal_model,
            causal=causal,
        )
        gas, shift = result.gas[:count], result.level_shift_c
        variance = result.std[:count] ** 2 + model_band_variance(model)
        _warn_misfit(record, result.fusion.misfit_warning, "the output model lacks physics")
        print(
            f"{args.reconstruction}: signal model {result.fusion.kind}; median std of the "
            f"estimate {np.median(np.sqrt(variance)):.4g} degC (the output model's band "
            f"included)"
        )
    written, ref = _write_gas(args, record, gas, variance)
    print(f"wrote {written}: gas temperature at {gas.size} of {record.tc1.size} samples")
    errors: dict[str, float] = {}
    if ref is not None:
        first = _first_order_gas(record, args, model.base_taus)[: gas.size]
        errors = _print_errors(record, model, first, gas, args.reconstruction)
    if args.json is not None:
        _write_json(args, model, errors, shift)
    if args.png:
        _plot(args, record, gas, ref, variance, half_sample_on=True)
    return 0


def _print_errors(
    record: Record,
    model: OutputModel,
    first: NDArray[np.float64],
    gas: NDArray[np.float64],
    reconstruction: str,
) -> dict[str, float]:
    """e_Tg and mean offset of the first-order and the compensated gas against the reference.

    Element k is the gas held over [t_k, t_k+1), so the reference is read half a sample on;
    e_Tg is also given with everything low-passed at the diagnosis's band edge, where the
    model, not the sensors' noise, decides.
    """
    import numpy as np
    from scipy import signal

    from ..effects.chain import fractional_shift
    from ..metrics import reconstruction_error_percent

    assert record.ref is not None
    truth = fractional_shift(record.ref, 0.5)[0][: gas.size]
    keep = np.isfinite(truth)
    truth, first, gas = truth[keep], first[keep], gas[keep]
    errors = [reconstruction_error_percent(truth, values) for values in (first, gas)]
    offsets = [float(np.mean(values - truth)) for values in (first, gas)]
    print(
        f"e_Tg ({reconstruction}) against the ref signal read half a sample on: "
        f"{errors[0]:.2f} % first order -> {errors[1]:.2f} % {model.name()}; mean offset "
        f"gas - ref {offsets[0]:+.3g} degC -> {offsets[1]:+.3g} degC"
    )
    found = {
        "e_tg_first_order_pct": errors[0],
        "e_tg_pct": errors[1],
        "offset_first_order_c": offsets[0],
        "offset_c": offsets[1],
    }
    if 0.0 < model.band_hz < 0.5 / record.dt:
        sos = signal.butter(4, model.band_hz, output="sos", fs=1.0 / record.dt)
        low, *band = (signal.sosfiltfilt(sos, values) for values in (truth, first, gas))
        errors = [reconstruction_error_percent(low, values) for values in band]
        print(
            f"e_Tg in the signal band (all low-passed at {model.band_hz:.4g} Hz, where the "
            f"model, not the noise, decides): {errors[0]:.2f} % first order -> "
            f"{errors[1]:.2f} %"
        )
        found |= {"e_tg_band_first_order_pct": errors[0], "e_tg_band_pct": errors[1]}
    return found


def _write_json(
    args: argparse.Namespace, model: OutputModel, errors: dict[str, float], shift: float
) -> None:
    """``--json``: the output model, the level shift and the errors against the reference."""
    import json

    from ..io import atomic_output

    document = {
        "source": str(args.data),
        "reconstruction": args.reconstruction,
        "output_model": model.summary(),
        "level_shift_c": shift,
        "against_ref": errors,
    }
    with atomic_output(args.json, args.force, [args.data]) as temporary:
        temporary.write_text(json.dumps(document, indent=2) + "\n")
    print(f"json: {args.json}")


def _first_order_gas(
    record: Record, args: argparse.Namespace, taus: tuple[float, float]
) -> NDArray[np.float64]:
    """The first-order reconstruction ``args`` asks for at ``taus`` (s), for comparison."""
    from ..fusion import fuse
    from ..reconstruct import reconstruct

    if args.reconstruction == "difference":
        return reconstruct(
            record.tc1,
            record.tc2,
            record.dt,
            *taus,
            phi=args.phi if args.phi is not None else 1.0,
            combine=args.combine,
            postfilter_hz=args.postfilter_hz,
            time=record.time,
        ).gas
    causal = args.reconstruction == "kalman-causal"
    return fuse(
        record.tc1, record.tc2, record.dt, *taus, model=args.signal_model, causal=causal
    ).gas


def model_band_variance(model: OutputModel) -> float:
    """Variance the output model's own uncertainty adds to its gas, (degrees C)**2.

    The rms 95 % band of the applied fit (the jackknife's, with what its free parameters
    move: :meth:`~tcomp_core.diagnose.identification.Identification.output_band_c`) as a
    variance; 0 when nothing is applied or the band is unknown.
    """
    from ..diagnose.uncertainty import Z95

    found = model.identification
    if not model.applied() or found is None:
        return 0.0
    band = found.output_band_c(model.applied())
    return (band / Z95) ** 2 if math.isfinite(band) else 0.0


def _write_gas(
    args: argparse.Namespace,
    record: Record,
    gas: NDArray[np.float64],
    variance: NDArray[np.float64] | None = None,
) -> tuple[Path, NDArray[np.float64] | None]:
    """Write the record's first ``gas.size`` samples with ``gas`` (and its variance).

    The gas is marked not valid (NaN: ``nan`` in CSV, a NaN temperature in a bag) where it
    rests on bridged readings or lies outside the physical range
    (:func:`~tcomp_core.io.screening.screen_gas`). Returns the path written and the matching
    part of the reference (None without one).
    """
    import numpy as np

    from ..io import write_series
    from ..io.screening import screen_gas

    count = gas.size
    gas = screen_gas(record.source, gas, record.left_out)
    if variance is not None:
        variance = np.where(np.isnan(gas), np.nan, variance)
    ref = None if record.ref is None else record.ref[:count]
    written = write_series(
        args.output,
        record.time[:count],
        record.tc1[:count],
        record.tc2[:count],
        ref,
        gas=gas,
        gas_variance=variance,
        overwrite=args.force,
        inputs=record,
    )
    return written, ref


def _plot(
    args: argparse.Namespace,
    record: Record,
    gas: NDArray[np.float64],
    ref: NDArray[np.float64] | None,
    variance: NDArray[np.float64] | None = None,
    *,
    half_sample_on: bool = False,
) -> None:
    """Write ``--png``.

    ``half_sample_on``: compare with the reference read half a sample on, as the compensated
    path's e_Tg does (:func:`_print_errors`).
    """
    import numpy as np

    from ..effects.chain import fractional_shift
    from ..plots import plot_reconstruction

    std = None if variance is None else np.sqrt(variance)
    label = "ref"
    if ref is not None and half_sample_on and record.ref is not None:
        ref, label = fractional_shift(record.ref, 0.5)[0][: gas.size], "ref half a sample on"
    path = plot_reconstruction(
        record.time,
        record.tc1,
        record.tc2,
        gas,
        args.png,
        ref=ref,
        std=std,
        title=str(args.data),
        ref_label=label,
    )
    print(f"wrote {path}")
