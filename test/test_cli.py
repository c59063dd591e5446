import json
import re
import subprocess
import sys

import numpy as np
import pytest
from sim_records import make_pair

from tcomp_core.cli import build_parser, main
from tcomp_core.io import read_record, write_csv

VERBS = [
    "simulate",
    "estimate",
    "reconstruct",
    "sweep",
    "study",
    "diagnose",
    "fit",
    "track",
    "process",
]


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_has_help(verb, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([verb, "--help"])
    assert exit_info.value.code == 0
    assert "usage: tcomp " + verb in capsys.readouterr().out


def test_parser_lists_every_verb():
    help_text = build_parser().format_help()
    for verb in VERBS:
        assert verb in help_text


@pytest.fixture
def simulated(tmp_path):
    csv, bag = tmp_path / "sim.csv", tmp_path / "sim_bag"
    status = main(
        [
            *("simulate", "--signal", "ramp", "--tau1", "0.03", "--tau2", "0.12"),
            *("--rate", "500", "--duration", "6", "-o", str(csv), "-o", str(bag)),
        ]
    )
    assert status == 0
    return csv, bag


@pytest.mark.parametrize("which", [0, 1], ids=["csv", "mcap"])
def test_simulate_then_estimate_recovers_tau(simulated, which, capsys):
    capsys.readouterr()
    assert main(["estimate", str(simulated[which]), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["method"] == "ml-eiv"
    assert payload["tau1"] == pytest.approx(0.03, rel=1e-9)
    assert payload["tau2"] == pytest.approx(0.12, rel=1e-9)
    assert payload["samples"] == 3000


def test_csv_and_bag_hold_the_same_samples(simulated):
    from_csv, from_bag = (read_record(path) for path in simulated)
    np.testing.assert_array_equal(from_csv.tc1, from_bag.tc1)
    np.testing.assert_array_equal(from_csv.tc2, from_bag.tc2)
    np.testing.assert_array_equal(from_csv.ref, from_bag.ref)
    np.testing.assert_allclose(from_csv.time, from_bag.time, atol=1e-9)


def test_estimate_all_methods_table(simulated, capsys):
    capsys.readouterr()
    assert main(["estimate", str(simulated[0]), "--method", "all", "--alpha", "0.25"]) == 0
    out = capsys.readouterr().out
    for method in ["tdr-kee", "gamma-ls", "gamma-tls", "beta-ls", "beta-tls", "beta-gtls"]:
        assert method in out


def test_estimate_says_when_the_data_do_not_pin_tau_down(simulated, tmp_path, capsys):
    """A 0.5 Hz sine seen by sensors of 20 and 100 ms: its τ1 interval spans far beyond ±20 %."""
    pair = make_pair(
        "sinusoid", tau1=0.02, tau2=0.1, duration=8.0, noise_percent=2.0, seed=6, freq_hz=0.5
    )
    slow = write_csv(tmp_path / "slow.csv", pair.time, pair.tc1, pair.tc2)
    capsys.readouterr()
    assert main(["estimate", str(slow)]) == 0
    out = capsys.readouterr().out
    said = r"ml-eiv: tau1's 95 % interval \S+ \.\. \S+ s is wider than \+-20 %"
    assert re.search(said, out), out
    assert main(["estimate", str(simulated[0])]) == 0  # a ramp pins both down
    assert "do not pin it down" not in capsys.readouterr().out


@pytest.mark.parametrize("suffix", ["gas.csv", "gas_bag"])
def test_reconstruct_round_trip_recovers_gas(simulated, tmp_path, suffix, capsys):
    output = tmp_path / suffix
    args = ["reconstruct", str(simulated[1]), "-o", str(output), "--reconstruction", "difference"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "e_Tg (combined)" in printed
    source = read_record(simulated[0])
    if suffix.endswith(".csv"):
        import csv

        with output.open() as handle:
            rows = list(csv.DictReader(handle))
        gas = np.array([float(row["gas"]) for row in rows])
    else:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        with AnyReader([output], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            connections = [c for c in reader.connections if c.topic == "/gas_temperature"]
            gas = np.array(
                [
                    reader.deserialize(raw, conn.msgtype).temperature
                    for conn, _, raw in reader.messages(connections=connections)
                ]
            )
    assert gas.size == source.tc1.size - 1
    # Noise-free data and exact time constants: the zero-order-held gas comes back exactly.
    np.testing.assert_allclose(gas, source.ref[:-1], rtol=1e-8)


@pytest.mark.slow
def test_reconstruct_defaults_to_the_smoother_and_falls_back_to_eq7(
    simulated, tmp_path, capsys, monkeypatch
):
    output = tmp_path / "gas.csv"
    assert main(["reconstruct", str(simulated[0]), "-o", str(output)]) == 0
    printed = capsys.readouterr().out
    assert "e_Tg (kalman) = " in printed  # the RTS smoother of both sensors
    smoothed = read_record(output, columns=("tc1", "tc2", "gas")).ref
    # No signal model can be used (here: none fits): Eq. (7), said on stderr, exit 0.
    import tcomp_core.fusion.record as record
    from tcomp_core.fusion import SignalModelFits

    def nothing_fits(*args, model="auto", **kwargs):
        return SignalModelFits([], {"random-walk": "no steady state"}, model)

    monkeypatch.setattr(record, "fit_signal_models", nothing_fits)
    assert main(["reconstruct", str(simulated[0]), "-o", str(output), "--force"]) == 0
    captured = capsys.readouterr()
    assert "no signal model of the gas could be used" in captured.err
    assert "Eq. (7)" in captured.err and "e_Tg (combined)" in captured.out
    fallback = read_record(output, columns=("tc1", "tc2", "gas")).ref
    assert fallback.size == smoothed.size and not np.array_equal(fallback, smoothed)


def test_reconstruct_refuses_to_overwrite(simulated, tmp_path, capsys):
    output = tmp_path / "gas.csv"
    output.write_text("keep me")
    assert main(["reconstruct", str(simulated[0]), "-o", str(output)]) == 1
    assert "gas.csv" in capsys.readouterr().err
    assert output.read_text() == "keep me"


def test_kalman_reconstruction_beats_eq7_against_the_ref(tmp_path, capsys):
    csv = tmp_path / "noisy.csv"
    simulate = ["simulate", "--signal", "ramp", "--noise", "2", "--duration", "6", "-o"]
    assert main([*simulate, str(csv)]) == 0
    errors = {}
    for reconstruction in ("difference", "kalman", "kalman-causal"):
        output = tmp_path / f"{reconstruction}.csv"
        status = main(
            [
                *("reconstruct", str(csv), "-o", str(output)),
                *("--reconstruction", reconstruction, "--signal-model", "random-walk"),
            ]
        )
        assert status == 0
        text = capsys.readouterr().out
        line = text.splitlines()[-1] if reconstruction != "difference" else text
        label = "combined" if reconstruction == "difference" else reconstruction
        errors[reconstruction] = float(line.split(f"e_Tg ({label}) = ")[1].split(" %")[0])
        written = read_record(output, columns=("tc1", "tc2", "gas"))
        assert written.tc1.size == 2999  # 6 s at 500 Hz, the last sample has no successor
    assert errors["kalman"] < errors["kalman-causal"] < errors["difference"]
    status = main(
        [
            *("reconstruct", str(csv), "-o", str(tmp_path / "x.csv")),
            *("--reconstruction", "kalman", "--postfilter-hz", "50"),
        ]
    )
    assert status == 1
    assert "apply to --reconstruction difference" in capsys.readouterr().err


def test_track_follows_a_changing_tau_and_writes_its_history(tmp_path, capsys):
    from tcomp_core.io import write_csv
    from tcomp_core.tracking import varying_lag_response

    dt, count = 0.002, 6000
    time = np.arange(count) * dt
    gas = 100 + 20 * np.sin(2 * np.pi * 3 * time) + 10 * np.sin(2 * np.pi * 17 * time)
    scale = np.where(time < 6.0, 1.0, 1.3)  # the flow slows down at 6 s: tau rises 30 %
    rng = np.random.default_rng(8)
    tc1 = varying_lag_response(gas, 0.02 * scale, dt) + rng.normal(0.0, 0.03, count)
    tc2 = varying_lag_response(gas, 0.1 * scale, dt) + rng.normal(0.0, 0.03, count)
    data = write_csv(tmp_path / "flow.csv", time, tc1, tc2)
    output = tmp_path / "track.csv"
    assert main(["track", str(data), "--memory-s", "0.5", "-o", str(output)]) == 0
    assert "ratio tau1/tau2 held at" in capsys.readouterr().out
    history = np.genfromtxt(output, delimiter=",", names=True)
    early, late = history["time"] < 5.0, history["time"] > 7.0
    assert np.median(history["tau1"][early]) == pytest.approx(0.02, rel=0.05)
    assert np.median(history["tau1"][late]) == pytest.approx(0.026, rel=0.05)
    assert np.median(history["tau2"][late]) == pytest.approx(0.13, rel=0.05)
    assert main(["track", str(data), "-o", str(output)]) == 1
    assert "pass --force" in capsys.readouterr().err


def test_sweep_writes_png_and_picks_a_frequency(simulated, tmp_path, capsys):
    png = tmp_path / "sweep.png"
    assert main(["sweep", str(simulated[0]), "--json", "--png", str(png)]) == 0
    payload = json.loads(capsys.readouterr().out.split("\nwrote")[0])
    assert payload["best_hz"] > payload["fundamental_hz"]
    assert png.stat().st_size > 1000


def test_study_prints_table_and_findings(tmp_path, capsys):
    png, table = tmp_path / "study.png", tmp_path / "study.json"
    args = ["study", "--runs", "3", "--noise-levels", "0", "2", "--signals", "ramp"]
    assert main([*args, "--png", str(png), "--json", str(table)]) == 0
    out = capsys.readouterr().out
    assert "ramp: e_tau1" in out and "beta-gtls" in out
    assert "[HOLDS] beta-gtls and gamma-tls agree" in out
    assert png.stat().st_size > 1000
    rows = json.loads(table.read_text())["rows"]
    assert len(rows) == 2 * 6


def test_missing_file_is_one_line_error(tmp_path, capsys):
    missing = tmp_path / "nowhere.csv"
    assert main(["estimate", str(missing)]) == 1
    err = capsys.readouterr().err
    assert "nowhere.csv" in err and err.count("\n") == 1


def test_constant_signal_reports_no_information(tmp_path, capsys):
    path = tmp_path / "flat.csv"
    time = (np.arange(100) * 0.01).tolist()
    rows = "\n".join(f"{t!r},300.0,300.0" for t in time)
    path.write_text("time,tc1,tc2\n" + rows + "\n")
    assert main(["estimate", str(path)]) == 1
    assert "no information" in capsys.readouterr().err


def test_console_script_entry_point_runs():
    completed = subprocess.run(
        [sys.executable, "-m", "tcomp_core.cli", "--version"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert completed.returncode == 0
    assert completed.stdout.startswith("tcomp ")


@pytest.mark.slow
def test_core_never_imports_rclpy():
    code = (
        "import sys, tcomp_core, tcomp_core.cli, tcomp_core.io, tcomp_core.study, "
        "tcomp_core.sweep, tcomp_core.plots, tcomp_core.window\n"
        "sys.exit(1 if 'rclpy' in sys.modules else 0)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_process_defaults_are_those_of_the_configs(tmp_path):
    from tcomp_core.cli.process import process_config
    from tcomp_core.process import ProcessConfig

    args = build_parser().parse_args(["process", "in_bag", "-o", str(tmp_path / "out")])
    assert process_config(args) == ProcessConfig()


def test_effect_registry_holds_every_effect_name_in_order():
    from tcomp_core.choices import EFFECT_NAMES
    from tcomp_core.effects import EFFECTS

    assert tuple(EFFECTS) == EFFECT_NAMES
    assert all(EFFECTS[name].name == name for name in EFFECT_NAMES)


def test_fit_and_diagnose_offer_exactly_the_effect_names(capsys):
    from tcomp_core.choices import EFFECT_NAMES

    for verb in ("diagnose", "fit"):
        with pytest.raises(SystemExit):
            main([verb, "--help"])
        help_text = " ".join(capsys.readouterr().out.split())
        assert ", ".join(EFFECT_NAMES) in help_text


def test_library_warnings_print_as_one_line_and_others_pass_through(monkeypatch, capsys):
    import warnings

    from tcomp_core.cli import estimate
    from tcomp_core.errors import TcompWarning

    def run(args):
        warnings.warn("input.mcap: cut off at byte 1234", TcompWarning, stacklevel=1)
        warnings.warn("input.mcap: cut off at byte 1234", TcompWarning, stacklevel=1)
        warnings.warn("not ours", UserWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(estimate, "run", run)
    with pytest.warns(UserWarning, match="not ours"):
        assert main(["estimate", "input.mcap"]) == 0
    line = "tcomp estimate: warning: input.mcap: cut off at byte 1234\n"
    assert capsys.readouterr().err == 2 * line


@pytest.mark.slow
def test_reconstruct_and_process_compensate_with_the_effects_asked_for(tmp_path, capsys):
    from tcomp_core.io import write_csv
    from tcomp_core.simulate_effects import simulate_effect

    sim = simulate_effect("delay", "multisine", duration=6.0, noise_percent=1.0, seed=21)
    data = tmp_path / "delayed.csv"
    write_csv(data, sim.time, sim.tc1, sim.tc2, sim.gas)
    report = tmp_path / "gas.json"
    arguments = ["reconstruct", str(data), "-o", str(tmp_path / "gas.csv"), "--json", str(report)]
    assert main([*arguments, "--effects", "delay", "--reconstruction", "kalman"]) == 0
    printed = capsys.readouterr().out
    assert "output model: first-order+delay" in printed
    assert "delay: prior (only the delay between the sensors is seen" in printed
    document = json.loads(report.read_text())
    assert document["output_model"]["name"] == "first-order+delay"
    assert document["output_model"]["params"]["delay_s"] == pytest.approx(0.008, rel=0.1)
    errors = document["against_ref"]
    assert errors["e_tg_pct"] < 0.5 * errors["e_tg_first_order_pct"]
    gas = read_record(tmp_path / "gas.csv", columns=("tc1", "tc2", "gas"))
    assert gas.tc1.size == sim.tc1.size - 1
    # Each sample with its variance: the Kalman estimate's plus the fit's own band.
    found = document["output_model"]["identification"]
    assert 0.0 < found["gas_band_c"] < found["gas_change_c"]
    variance = read_record(tmp_path / "gas.csv", columns=("tc1", "tc2", "gas_variance")).ref
    assert np.all(variance >= (found["gas_band_c"] / 1.959963984540054) ** 2)
    # tcomp process publishes the same model's causal reconstruction.
    out = tmp_path / "processed.csv"
    assert main(["process", str(data), "-o", str(out), "--effects", "delay", "--no-diagnose"]) == 0
    assert "gas published with first-order+delay" in capsys.readouterr().out
    # Refusals name the problem.
    assert main([*arguments, "--force"]) == 1
    assert "--json describes the output model of --effects" in capsys.readouterr().err
    assert main([*arguments, "--force", "--effects", "delay,smoke"]) == 1
    assert "smoke" in capsys.readouterr().err
    assert (
        main([*arguments, "--force", "--effects", "auto", "--tau1", "0.02", "--tau2", "0.1"]) == 1
    )
    assert "--effects fits tau1 and tau2" in capsys.readouterr().err
