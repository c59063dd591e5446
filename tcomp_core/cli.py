"""The ``tcomp`` command line: the verbs that simulate, estimate, reconstruct, track, process.

Also sweep, study, diagnose and fit.

DATA arguments are a CSV file (``time,tc1,tc2[,ref]``) or a rosbag2 MCAP bag (directory or
``.mcap`` file) with ``sensor_msgs/msg/Temperature`` on ``/tc1/temperature``,
``/tc2/temperature`` and optionally ``/tref/temperature``. Errors are printed as one line naming
the file, column or topic, sample and value, with exit status 1.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from . import __version__
from .cli_diagnose import add_diagnose_commands
from .cli_process import add_process_command
from .cli_track import add_track_command
from .errors import TcompError
from .estimators import METHODS, PHI_METHODS, Estimate, estimate
from .estimators.mleiv import phi_from_data
from .fusion import MODELS, fit_fusion_model, fuse
from .io import DEFAULT_TOPICS, Record, read_record, write_series
from .metrics import reconstruction_error_percent
from .reconstruct import COMBINATIONS, reconstruct
from .simulate import PAPER_DT, PAPER_TAU1, PAPER_TAU2, SIGNALS, simulate_pair

__all__ = ["build_parser", "main"]


def _positive_float(text: str) -> float:
    value = float(text)
    if not (np.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
    return value


def _phi(text: str) -> float | None:
    """``--phi``: a ratio > 0, or ``auto`` (None: measured from the data)."""
    return None if text == "auto" else _positive_float(text)


#: Choices of ``reconstruct --reconstruction``.
RECONSTRUCTIONS = ("difference", "kalman", "kalman-causal")


def _add_data_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("data", type=Path, help="CSV file or rosbag2 MCAP bag")
    parser.add_argument(
        "--topics",
        nargs="+",
        metavar="TOPIC",
        help=f"bag topics of tc1, tc2 and optionally ref (default {' '.join(DEFAULT_TOPICS)})",
    )
    parser.add_argument(
        "--columns",
        nargs="+",
        metavar="COLUMN",
        help="CSV columns of tc1, tc2 and optionally ref (default tc1 tc2 ref)",
    )


def _add_estimator_arguments(parser: argparse.ArgumentParser, allow_all: bool = False) -> None:
    choices = [*METHODS, "all"] if allow_all else list(METHODS)
    parser.add_argument(
        "--method", choices=choices, default="beta-gtls", help="estimator (default beta-gtls)"
    )
    parser.add_argument(
        "--prefilter-hz",
        type=_positive_float,
        help="zero-phase Butterworth pre-filter bandwidth before estimation, Hz",
    )
    parser.add_argument(
        "--phi",
        type=_phi,
        default=1.0,
        help="noise variance ratio sigma1^2/sigma2^2 for beta-gtls and ml-eiv (default 1); "
        "'auto' measures it from the top of the two spectra",
    )
    parser.add_argument(
        "--alpha",
        type=_positive_float,
        help="time constant ratio tau1/tau2 for tdr-kee (estimated at crossovers if omitted)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``tcomp`` with one sub-command per verb."""
    parser = argparse.ArgumentParser(
        prog="tcomp",
        description="Two-thermocouple lag compensation (Hung, Irwin, Kee & McLoone 2005).",
    )
    parser.add_argument("--version", action="version", version=f"tcomp {__version__}")
    verbs = parser.add_subparsers(dest="verb", required=True, metavar="VERB")

    sim = verbs.add_parser(
        "simulate",
        help="write simulated two-thermocouple data (CSV and/or MCAP bag)",
        description="Simulate two first-order thermocouples in one gas (Fig. 2) and write the "
        "record; the true gas temperature goes to the ref column/topic.",
    )
    sim.add_argument(
        "-o",
        "--output",
        type=Path,
        action="append",
        required=True,
        help="output path, repeatable: *.csv for CSV, anything else for a rosbag2 MCAP bag",
    )
    sim.add_argument("--signal", choices=SIGNALS, default="sinusoid", help="gas temperature")
    sim.add_argument("--tau1", type=_positive_float, default=PAPER_TAU1, help="tau1, s")
    sim.add_argument("--tau2", type=_positive_float, default=PAPER_TAU2, help="tau2, s")
    sim.add_argument(
        "-K", "--noise", type=float, default=0.0, help="noise level K, percent (Eq. 22)"
    )
    sim.add_argument("--phi", type=_positive_float, default=1.0, help="noise ratio s1^2/s2^2")
    sim.add_argument(
        "--rate", type=_positive_float, default=1.0 / PAPER_DT, help="sample rate, Hz"
    )
    sim.add_argument("--duration", type=_positive_float, default=10.0, help="length, s")
    sim.add_argument("--seed", type=int, default=0, help="noise seed")
    sim.add_argument("--no-ref", action="store_true", help="leave out the true gas temperature")
    sim.add_argument("--force", action="store_true", help="overwrite existing outputs")
    sim.set_defaults(handler=_cmd_simulate)

    est = verbs.add_parser(
        "estimate",
        help="estimate tau1 and tau2 from two thermocouple signals",
        description="Estimate both time constants from the two signals alone.",
    )
    _add_data_arguments(est)
    _add_estimator_arguments(est, allow_all=True)
    est.add_argument("--json", action="store_true", help="print JSON instead of a table")
    est.set_defaults(handler=_cmd_estimate)

    rec = verbs.add_parser(
        "reconstruct",
        help="reconstruct the gas temperature (Eq. 7 or a Kalman smoother)",
        description="Estimate tau1, tau2 (or take them as given) and reconstruct the gas "
        "temperature from both thermocouples: through the difference equation (Eq. 7), or "
        "by a Kalman smoother (or causal filter) of both sensors whose gas temperature model "
        "and settings are fitted to the data by maximum likelihood.",
    )
    _add_data_arguments(rec)
    _add_estimator_arguments(rec)
    rec.add_argument(
        "-o", "--output", type=Path, required=True, help="*.csv or an MCAP bag directory"
    )
    rec.add_argument("--tau1", type=_positive_float, help="use this tau1 (s), skip estimation")
    rec.add_argument("--tau2", type=_positive_float, help="use this tau2 (s), skip estimation")
    rec.add_argument(
        "--postfilter-hz", type=_positive_float, help="5th-order zero-phase post-filter, Hz"
    )
    rec.add_argument(
        "--combine",
        choices=COMBINATIONS,
        default="inverse-variance",
        help="how the two reconstructions are combined (default inverse-variance)",
    )
    rec.add_argument(
        "--reconstruction",
        choices=RECONSTRUCTIONS,
        default="difference",
        help="difference: Eq. (7) (default); kalman: RTS smoother of both sensors; "
        "kalman-causal: the forward filter alone, as the node runs it",
    )
    rec.add_argument(
        "--signal-model",
        choices=["auto", *MODELS],
        default="auto",
        help="gas temperature model of the Kalman reconstructions (default auto: the most "
        "likely, penalised by its number of settings)",
    )
    rec.add_argument("--png", type=Path, help="also plot the reconstruction to this PNG")
    rec.add_argument("--force", action="store_true", help="overwrite an existing output")
    rec.set_defaults(handler=_cmd_reconstruct)

    swp = verbs.add_parser(
        "sweep",
        help="tau estimates against pre-filter bandwidth (Fig. 10)",
        description="Estimate tau1, tau2 after pre-filtering at a range of bandwidths and pick "
        "the best pre-filtering frequency (first major local maximum above the fundamental).",
    )
    _add_data_arguments(swp)
    swp.add_argument("--method", choices=METHODS, default="beta-gtls")
    swp.add_argument("--phi", type=_positive_float, default=1.0)
    swp.add_argument("--alpha", type=_positive_float)
    swp.add_argument(
        "--bandwidths", type=_positive_float, nargs="+", metavar="HZ", help="bandwidths, Hz"
    )
    swp.add_argument("--png", type=Path, help="write the Fig. 10 plot to this PNG")
    swp.add_argument("--json", action="store_true", help="print JSON instead of a table")
    swp.set_defaults(handler=_cmd_sweep)

    sty = verbs.add_parser(
        "study",
        help="Monte Carlo study of Fig. 4",
        description="e_tau against noise level K for every method on the sinusoid and the "
        "periodic ramp (tau1 = 0.0238 s, tau2 = 0.1168 s, tau_s = 0.002 s, 10 s runs).",
    )
    sty.add_argument("--runs", type=int, default=100, help="runs per noise level (default 100)")
    sty.add_argument(
        "--noise-levels", type=float, nargs="+", default=[0, 1, 2, 3, 4, 5, 6], metavar="K"
    )
    sty.add_argument("--signals", nargs="+", choices=SIGNALS, default=["sinusoid", "ramp"])
    sty.add_argument("--phi", type=_positive_float, default=1.0, help="noise ratio of the data")
    sty.add_argument("--seed", type=int, default=0)
    sty.add_argument("--png", type=Path, default=Path("out/study.png"), help="figure path")
    sty.add_argument("--json", type=Path, help="also write the table as JSON to this file")
    sty.set_defaults(handler=_cmd_study)

    add_diagnose_commands(verbs, _add_data_arguments)
    add_track_command(verbs, _add_data_arguments, read_data)
    add_process_command(verbs)
    return parser


def read_data(args: argparse.Namespace) -> Record:
    """Read the DATA argument with the ``--topics`` / ``--columns`` options."""
    topics = columns = None
    if args.topics:
        if len(args.topics) not in (2, 3):
            raise TcompError("--topics takes the tc1 and tc2 topics and optionally ref")
        topics = (*args.topics, None) if len(args.topics) == 2 else tuple(args.topics)
    if args.columns:
        if len(args.columns) not in (2, 3):
            raise TcompError("--columns takes the tc1 and tc2 columns and optionally ref")
        columns = (*args.columns, None) if len(args.columns) == 2 else tuple(args.columns)
    return read_record(args.data, topics=topics, columns=columns)


def _estimate(record: Record, args: argparse.Namespace, method: str) -> Estimate:
    return estimate(
        record.tc1,
        record.tc2,
        record.dt,
        method,  # type: ignore[arg-type]
        phi=args.phi if method in PHI_METHODS else 1.0,
        alpha=args.alpha if method == "tdr-kee" else None,
        prefilter_hz=args.prefilter_hz,
    )


def _cmd_simulate(args: argparse.Namespace) -> int:
    data = simulate_pair(
        args.signal,
        tau1=args.tau1,
        tau2=args.tau2,
        dt=1.0 / args.rate,
        duration=args.duration,
        noise_percent=args.noise,
        phi=args.phi,
        seed=args.seed,
    )
    for path in args.output:
        written = write_series(
            path,
            data.time,
            data.tc1,
            data.tc2,
            None if args.no_ref else data.gas,
            overwrite=args.force,
        )
        print(
            f"wrote {written}: {args.signal}, {data.time.size} samples at {args.rate:g} Hz, "
            f"tau1 = {args.tau1:g} s, tau2 = {args.tau2:g} s, K = {args.noise:g} %"
        )
    return 0


def _estimate_row(result: Estimate) -> str:
    raw = ", ".join(f"{key}={value:.6g}" for key, value in result.params.items())
    return (
        f"{result.method:<10} {result.tau1:>10.6f} {result.tau2:>10.6f} {result.alpha:>8.4f} "
        f"{result.condition:>9.3g}  {raw}"
    )


def _cmd_estimate(args: argparse.Namespace) -> int:
    record = read_data(args)
    methods = METHODS if args.method == "all" else (args.method,)
    results: list[Estimate] = []
    failures: dict[str, str] = {}
    for method in methods:
        try:
            results.append(_estimate(record, args, method))
        except (TcompError, ValueError) as exc:
            if len(methods) == 1:
                raise
            failures[method] = str(exc)
    if args.json:
        payload: dict[str, object] = {
            "source": record.source,
            "samples": int(record.tc1.size),
            "dt": record.dt,
        }
        if len(methods) == 1:
            payload.update(results[0].to_dict())
        else:
            payload["estimates"] = [result.to_dict() for result in results]
            payload["failures"] = failures
        print(json.dumps(payload, indent=2))
        return 0
    print(f"{record.source}: {record.tc1.size} samples, dt = {record.dt:.6g} s")
    print(f"{'method':<10} {'tau1 (s)':>10} {'tau2 (s)':>10} {'alpha':>8} {'condition':>9}  raw")
    for result in results:
        print(_estimate_row(result))
    for method, text in failures.items():
        print(f"{method:<10} failed: {text}")
    return 0


def _cmd_reconstruct(args: argparse.Namespace) -> int:
    record = read_data(args)
    if (args.tau1 is None) != (args.tau2 is None):
        raise TcompError("give both --tau1 and --tau2, or neither to estimate them")
    if args.tau1 is None:
        result = _estimate(record, args, args.method)
        tau1, tau2 = result.tau1, result.tau2
        print(f"{args.method}: tau1 = {tau1:.6f} s, tau2 = {tau2:.6f} s")
    else:
        tau1, tau2 = args.tau1, args.tau2
    if args.reconstruction != "difference":
        return _reconstruct_kalman(record, args, tau1, tau2)
    recon = reconstruct(
        record.tc1,
        record.tc2,
        record.dt,
        tau1,
        tau2,
        phi=args.phi if args.phi is not None else phi_from_data(record.tc1, record.tc2, record.dt),
        combine=args.combine,
        postfilter_hz=args.postfilter_hz,
        time=record.time,
    )
    count = recon.gas.size
    written, ref = _write_gas(args, record, recon.gas)
    print(
        f"wrote {written}: gas temperature at {count} of {record.tc1.size} samples "
        f"(the last sample has no successor to reconstruct from), weight of tc1 "
        f"{recon.weight1:.3f}"
    )
    if ref is not None:
        for label, values in (("tc1", recon.gas1), ("tc2", recon.gas2), ("combined", recon.gas)):
            error = reconstruction_error_percent(ref, values)
            print(f"e_Tg ({label}) = {error:.2f} % against the ref signal")
    if args.png:
        _plot_reconstruction(args, record, recon.gas, ref)
    return 0


def _write_gas(
    args: argparse.Namespace, record: Record, gas: np.ndarray
) -> tuple[Path, np.ndarray | None]:
    """Write the record's first ``gas.size`` samples with ``gas`` to ``--output``.

    Returns the path written and the matching part of the reference (None without one).
    """
    count = gas.size
    ref = None if record.ref is None else record.ref[:count]
    written = write_series(
        args.output,
        record.time[:count],
        record.tc1[:count],
        record.tc2[:count],
        ref,
        gas=gas,
        overwrite=args.force,
    )
    return written, ref


def _plot_reconstruction(
    args: argparse.Namespace, record: Record, gas: np.ndarray, ref: np.ndarray | None
) -> None:
    series = {"tc1": record.tc1, "tc2": record.tc2, "gas (reconstructed)": gas}
    if ref is not None:
        series["ref"] = ref
    from .plots import plot_reconstruction

    print(f"wrote {plot_reconstruction(record.time, series, args.png, str(args.data))}")


def _reconstruct_kalman(record: Record, args: argparse.Namespace, tau1: float, tau2: float) -> int:
    """``reconstruct --reconstruction kalman[-causal]``."""
    if args.postfilter_hz is not None or args.combine != "inverse-variance":
        raise TcompError("--postfilter-hz and --combine apply to --reconstruction difference")
    model, _, _ = fit_fusion_model(
        record.tc1, record.tc2, record.dt, tau1, tau2, model=args.signal_model
    )
    causal = args.reconstruction == "kalman-causal"
    fused = fuse(record.tc1, record.tc2, record.dt, tau1, tau2, model=model, causal=causal)
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
    written, ref = _write_gas(args, record, gas)
    print(f"wrote {written}: gas temperature at {count} of {record.tc1.size} samples")
    if ref is not None:
        error = reconstruction_error_percent(ref, gas)
        print(f"e_Tg ({args.reconstruction}) = {error:.2f} % against the ref signal")
    if args.png:
        _plot_reconstruction(args, record, gas, ref)
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from .sweep import prefilter_sweep

    record = read_data(args)
    result = prefilter_sweep(
        record.tc1,
        record.tc2,
        record.dt,
        args.method,
        bandwidths_hz=args.bandwidths,
        phi=args.phi if args.method in PHI_METHODS else 1.0,
        alpha=args.alpha if args.method == "tdr-kee" else None,
    )
    if args.json:
        print(
            json.dumps(
                {
                    "method": result.method,
                    "fundamental_hz": result.fundamental_hz,
                    "best_hz": result.best_hz,
                    "best_is_peak": result.best_is_peak,
                    "bandwidths_hz": result.bandwidths_hz.tolist(),
                    "tau1": [None if np.isnan(v) else float(v) for v in result.tau1],
                    "tau2": [None if np.isnan(v) else float(v) for v in result.tau2],
                    "failures": list(result.failures),
                },
                indent=2,
            )
        )
    else:
        print(f"{record.source}: fundamental {result.fundamental_hz:.4g} Hz, {result.method}")
        print(f"{'bandwidth (Hz)':>14} {'tau1 (s)':>10} {'tau2 (s)':>10}")
        for index, bandwidth in enumerate(result.bandwidths_hz):
            mark = "  <- best" if index == result.best_index else ""
            if result.failures[index]:
                print(f"{bandwidth:>14.4g}     failed: {result.failures[index]}")
            else:
                print(
                    f"{bandwidth:>14.4g} {result.tau1[index]:>10.6f} "
                    f"{result.tau2[index]:>10.6f}{mark}"
                )
        if result.best_hz is None:
            print("no bandwidth gave an estimate")
        else:
            kind = "first major local maximum" if result.best_is_peak else "largest estimate"
            print(f"best pre-filtering frequency: {result.best_hz:.4g} Hz ({kind})")
    if args.png:
        from .plots import plot_sweep

        print(f"wrote {plot_sweep(result, args.png)}")
    return 0


def _cmd_study(args: argparse.Namespace) -> int:
    from .plots import plot_study
    from .study import StudyConfig, check_findings, format_table, run_study, summarise_findings

    config = StudyConfig(
        signals=tuple(args.signals),
        noise_levels=tuple(args.noise_levels),
        runs=args.runs,
        phi=args.phi,
        seed=args.seed,
    )
    result = run_study(config, progress=lambda line: print(line, file=sys.stderr))
    print(format_table(result))
    print(summarise_findings(check_findings(result)))
    print(f"wrote {plot_study(result, args.png)}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result.to_dict(), indent=2))
        print(f"wrote {args.json}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``tcomp`` with ``argv`` (``sys.argv[1:]`` by default); returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.handler(args)
    except (TcompError, ValueError, OSError) as exc:
        print(f"tcomp {args.verb}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
