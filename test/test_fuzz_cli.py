"""Property-based fuzzing of the ``tcomp`` verbs (issue 13, design.md convention 11).

Small generated records (empty to a few hundred rows; constant, zero, extreme, NaN, spiky or
well-behaved columns; duplicate or uneven times) go through the verbs in-process. The outcome is
exit 0 with finite outputs, or exit 1 with one stderr line naming the file: never a traceback,
never an exception out of ``main``, never a non-finite value in an output file.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tcomp_core.cli import main

SETTINGS = settings(
    derandomize=True,
    max_examples=60,
    deadline=None,  # a verb that does work on a good record takes a second or two
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
COLUMN_KINDS = ["lagged", "constant", "zero", "extreme", "nan", "spikes", "noise"]


def column(kind, time, rng, lag):
    if kind == "lagged":  # a smooth signal, shifted in phase per column
        return 300 + 50 * np.sin(2 * np.pi * 5 * time - lag) + rng.normal(0, 0.5, time.size)
    if kind == "constant":
        return np.full(time.size, 21.5)
    if kind == "zero":
        return np.zeros(time.size)
    if kind == "extreme":
        return np.where(rng.random(time.size) < 0.5, 1e300, -1e300)
    if kind == "nan":
        values = rng.normal(300, 5, time.size)
        values[rng.random(time.size) < 0.2] = np.nan
        return values
    if kind == "spikes":
        values = rng.normal(300, 0.1, time.size)
        values[:: max(1, time.size // 7)] = 1e6
        return values
    return rng.normal(0, 1, time.size)


@st.composite
def records(draw):
    rows = draw(st.sampled_from([0, 1, 2, 4, 17, 60, 300, 1200]))
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    timing = draw(st.sampled_from(["uniform", "duplicates", "uneven", "backwards"]))
    time = np.arange(rows) * 0.002
    if timing == "duplicates" and rows > 3:
        time[rows // 2] = time[rows // 2 - 1]
    elif timing == "uneven":
        time = np.sort(rng.uniform(0, rows * 0.002, rows))
    elif timing == "backwards" and rows > 3:
        time = time[::-1].copy()
    kinds = draw(st.tuples(st.sampled_from(COLUMN_KINDS), st.sampled_from(COLUMN_KINDS)))
    return time, column(kinds[0], time, rng, 0), column(kinds[1], time, rng, 1)


def write(path, time, tc1, tc2):
    lines = ["time,tc1,tc2"]
    rows = zip(time.tolist(), tc1.tolist(), tc2.tolist(), strict=True)
    lines += [f"{t!r},{a!r},{b!r}" for t, a, b in rows]
    path.write_text("\n".join(lines) + "\n")


VERBS = {
    "estimate": lambda data, out: ["estimate", data],
    "reconstruct": lambda data, out: ["reconstruct", data, "-o", out, "--force"],
    "process": lambda data, out: ["process", data, "-o", out, "--force", "--no-diagnose"],
    "track": lambda data, out: ["track", data, "-o", out, "--force", "--memory-s", "0.2"],
    "sweep": lambda data, out: ["sweep", data, "--bandwidths", "20", "50"],
    "diagnose": lambda data, out: ["diagnose", data],
}


def check_outcome(code, captured, data, out):
    assert "Traceback" not in captured.err
    if code == 0:
        if out.exists():
            table = np.genfromtxt(out, delimiter=",", names=True)
            for name in table.dtype.names or ():
                values = np.atleast_1d(table[name])
                values = values[~np.isnan(values)]  # empty cells: pairs not reconstructed
                assert np.isfinite(values).all(), name
        return
    errors = [line for line in captured.err.splitlines() if "error:" in line]
    assert code == 1 and len(errors) == 1, captured.err
    assert str(data) in errors[0] or data.name in errors[0], errors[0]


@pytest.mark.slow
@pytest.mark.parametrize("verb", sorted(VERBS))
def test_verbs_on_generated_records_exit_cleanly(verb, tmp_path_factory, capsys):
    @SETTINGS
    @given(records())
    def run(record):
        directory = tmp_path_factory.mktemp(verb)
        data, out = directory / "in.csv", directory / "out.csv"
        write(data, *record)
        try:
            code = main(VERBS[verb](str(data), str(out)))
        except SystemExit as exc:  # argparse only: usage errors are exit 2
            code = exc.code
        check_outcome(code, capsys.readouterr(), data, out)

    run()


def test_constant_and_short_records_get_one_line_errors(tmp_path, capsys):
    # The cases the issue lists: diagnose on 2 and 4 rows, track and diagnose on zeros.
    for rows, kind, verb in ((2, "lagged", "diagnose"), (4, "lagged", "diagnose")):
        data = tmp_path / f"{verb}_{rows}.csv"
        time = np.arange(rows) * 0.002
        write(data, time, *(column(kind, time, np.random.default_rng(0), k) for k in (0, 1)))
        assert main([verb, str(data)]) == 1
        check_outcome(1, capsys.readouterr(), data, tmp_path / "none")
    time = np.arange(2000) * 0.002
    zeros = tmp_path / "zeros.csv"
    write(zeros, time, np.zeros(2000), np.zeros(2000))
    for verb in ("track", "diagnose"):
        assert main([verb, str(zeros)]) == 1
        err = capsys.readouterr().err
        assert "zeros.csv" in err and "constant" in err and "Traceback" not in err


@pytest.mark.slow
def test_a_good_record_passes_every_verb(tmp_path, capsys):
    # The property must not be met by refusing everything.
    rng = np.random.default_rng(1)
    time = np.arange(3000) * 0.002
    gas = 300 + 50 * np.sin(2 * np.pi * 3 * time)
    pole1, pole2 = math.exp(-0.002 / 0.0238), math.exp(-0.002 / 0.1168)
    tc1, tc2 = np.empty_like(gas), np.empty_like(gas)
    tc1[0] = tc2[0] = gas[0]
    for k in range(1, gas.size):
        tc1[k] = pole1 * tc1[k - 1] + (1 - pole1) * gas[k - 1]
        tc2[k] = pole2 * tc2[k - 1] + (1 - pole2) * gas[k - 1]
    data, out = tmp_path / "good.csv", tmp_path / "out.csv"
    write(data, time, tc1 + rng.normal(0, 0.2, time.size), tc2 + rng.normal(0, 0.2, time.size))
    for verb in ("estimate", "reconstruct", "process", "track"):
        assert main(VERBS[verb](str(data), str(out))) == 0, capsys.readouterr().err
        check_outcome(0, capsys.readouterr(), data, out)
