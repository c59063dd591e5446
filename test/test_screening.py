"""One boundary for every verb (issue 26, item 1): invalid readings left out, counted, named.

A file with glitches (1e300 from a failed conversion, readings of 3e8 °C, NaN cells, a repeated
row) gets one verdict from ``estimate``, ``reconstruct`` and ``process``: the same samples left
out with a warning naming the first, τ as on the clean file, and no gas written where it would
rest on a left-out reading or lie outside the physical range.
"""

import csv
import math

import numpy as np
import pytest

from tcomp_core.cli import main
from tcomp_core.errors import DataError, InvalidReadingsWarning
from tcomp_core.io import read_record, write_csv
from tcomp_core.io.screening import MAX_BRIDGE_SAMPLES, VALID_RANGE_C, screen_gas
from tcomp_core.online.pairing import DEFAULT_VALID_RANGE
from tcomp_core.simulate import simulate_pair

#: Rows (0-based samples) given hostile tc1 readings, and what.
GLITCHES = {300: 1e300, 301: 1e300, 1200: math.nan, 2400: 3e8, 3100: -math.inf}


@pytest.fixture(scope="module")
def pair():
    return simulate_pair("multisine", noise_percent=1.0, seed=26, warmup=1.0, duration=8.0)


def _write(path, pair, tc1, extra_rows=()):
    write_csv(path, pair.time, tc1, pair.tc2)
    if extra_rows:
        with path.open("a", newline="") as handle:
            csv.writer(handle).writerows(extra_rows)
    return path


@pytest.fixture
def files(tmp_path, pair):
    glitched = pair.tc1.copy()
    for index, value in GLITCHES.items():
        glitched[index] = value
    return _write(tmp_path / "clean.csv", pair, pair.tc1), _write(
        tmp_path / "glitched.csv", pair, glitched
    )


def test_the_node_and_the_readers_share_one_range():
    assert DEFAULT_VALID_RANGE == VALID_RANGE_C == (-273.15, 2000.0)


def test_glitches_are_bridged_counted_and_named(files):
    with pytest.warns(InvalidReadingsWarning) as caught:
        record = read_record(files[1])
    (message,) = [str(w.message) for w in caught]
    assert "left out 5 column 'tc1' reading(s) not finite or outside -273.15..2000 °C" in message
    assert "the first at row 302: 1e+300" in message
    assert record.left_out is not None
    assert np.flatnonzero(record.left_out).tolist() == sorted(GLITCHES)
    assert np.all((record.tc1 > 0.0) & (record.tc1 < 2000.0))


def test_estimate_gives_the_clean_files_tau(files, capsys):
    taus = []
    for path in files:
        assert main(["estimate", str(path), "--json"]) == 0
        payload = capsys.readouterr().out
        taus.append([float(v) for v in (_json(payload)["tau1"], _json(payload)["tau2"])])
    np.testing.assert_allclose(taus[1], taus[0], rtol=0.002)


def _json(text):
    import json

    return json.loads(text)


@pytest.mark.slow
def test_reconstruct_writes_no_gas_on_a_left_out_reading(files, tmp_path, capsys):
    output = tmp_path / "gas.csv"
    assert main(["reconstruct", str(files[1]), "-o", str(output)]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "left out 5 column 'tc1'" in err
    assert "no gas written at 9 sample(s) that rest on bridged readings" in err
    gas = np.genfromtxt(output, delimiter=",", names=True)["gas"]
    blank = np.flatnonzero(np.isnan(gas)).tolist()
    # Element k rests on readings k and k + 1: both neighbours of each bridged sample.
    expected = sorted({k for index in GLITCHES for k in (index - 1, index)})
    assert blank == expected


@pytest.mark.slow
def test_process_leaves_out_the_same_readings(files, tmp_path, capsys):
    output = tmp_path / "out.csv"
    assert main(["process", str(files[1]), "-o", str(output), "--no-diagnose"]) == 0
    err = capsys.readouterr().err
    assert "dropped 5 tc1 temperatures not finite or outside the physical range" in err


def test_a_long_broken_stretch_is_refused_with_its_place(tmp_path, pair):
    broken = pair.tc1.copy()
    broken[1000 : 1001 + MAX_BRIDGE_SAMPLES] = math.nan
    path = _write(tmp_path / "broken.csv", pair, broken)
    with (
        pytest.warns(InvalidReadingsWarning),
        pytest.raises(DataError, match=r"broken\.csv .*: 9 samples in a row .* from row 1002 to "),
    ):
        read_record(path)


def test_invalid_ends_are_cut_without_bridging(tmp_path, pair):
    cut = pair.tc1.copy()
    cut[:50] = 2500.0  # above the range: a thermocouple that was not yet connected
    cut[-3:] = math.nan
    with pytest.warns(InvalidReadingsWarning, match="left out 53 column 'tc1'"):
        record = read_record(_write(tmp_path / "ends.csv", pair, cut))
    assert record.tc1.size == pair.tc1.size - 53 and record.left_out is None
    assert record.time[0] == pytest.approx(pair.time[50])


def test_readings_all_out_of_range_are_refused(tmp_path, pair):
    path = _write(tmp_path / "huge.csv", pair, pair.tc1 * 1e6)
    with (
        pytest.warns(InvalidReadingsWarning),
        pytest.raises(DataError, match="no sample has valid readings of both column 'tc1'"),
    ):
        read_record(path)


def test_a_repeated_row_is_left_out(tmp_path, pair):
    time = np.insert(pair.time, 11, pair.time[10])
    tc1, tc2 = np.insert(pair.tc1, 11, 0.0), np.insert(pair.tc2, 11, 0.0)
    path = write_csv(tmp_path / "twice.csv", time, tc1, tc2)
    with pytest.warns(
        InvalidReadingsWarning, match=r"repeats the one before \(the first at row 13"
    ):
        record = read_record(path)
    np.testing.assert_array_equal(record.tc1, pair.tc1)


def test_a_gas_outside_the_range_is_not_written():
    gas = np.array([20.0, -300.0, 2500.0, math.nan, 100.0])
    with pytest.warns(InvalidReadingsWarning, match=r"no gas written at 2 sample\(s\) where"):
        screened = screen_gas("here", gas, None)
    assert np.isnan(screened[1:4]).all() and screened[[0, 4]].tolist() == [20.0, 100.0]


@pytest.mark.parametrize(("rate", "warned"), [(500, False), (20_000, True)])
def test_eq7_says_when_it_amplifies_noise_far_beyond_the_readings(tmp_path, capsys, rate, warned):
    fast = simulate_pair("multisine", dt=1.0 / rate, duration=1.0, noise_percent=1.0, seed=7)
    path = write_csv(tmp_path / "fast.csv", fast.time, fast.tc1, fast.tc2)
    command = ["reconstruct", str(path), "--reconstruction", "difference"]
    assert main([*command, "-o", str(tmp_path / "gas.csv")]) == 0
    err = capsys.readouterr().err
    assert ("Eq. (7) multiplies the readings' noise" in err) is warned, err
    # A post-filter is the user's answer to it: no warning then.
    assert main([*command, "--postfilter-hz", "100", "-o", str(tmp_path / "filtered.csv")]) == 0
    assert "multiplies" not in capsys.readouterr().err
