"""Issue 27: the reconstruction picture shows what a user looks for.

A zoom short enough to see single cycles where the signal moves most, the whole record as
context, time from the start of the record, the error in its own panel, a legend naming every
line.
"""

import numpy as np
import pytest

from tcomp_core.cli import main
from tcomp_core.io import write_csv
from tcomp_core.plots import (
    busiest_window,
    reconstruction_figure,
    signal_frequency_hz,
    zoom_length,
)

EPOCH = 1.7e9  # a bag's stamps: seconds since 1970


def _noisy(values, sigma, seed):
    return values + sigma * np.random.default_rng(seed).standard_normal(values.size)


def test_the_zoom_holds_five_cycles_of_a_tone_and_of_a_broadband_signal():
    dt = 1e-3
    time = np.arange(20_000) * dt
    tone = _noisy(50.0 + 10.0 * np.sin(2 * np.pi * 10.0 * time), 0.2, 1)
    assert signal_frequency_hz(tone, dt) == pytest.approx(10.0, rel=0.05)
    assert zoom_length(tone, dt) * dt == pytest.approx(0.5, rel=0.05)
    # 1-100 Hz of equal amplitude: the strongest bin alone (1 Hz, 5 s for five periods) would
    # hide every fast cycle.
    rng = np.random.default_rng(2)
    tones = sum(
        np.sin(2 * np.pi * f * time + rng.uniform(0, 2 * np.pi)) for f in np.arange(1.0, 101.0)
    )
    broadband = _noisy(50.0 + tones, 0.2, 3)
    assert zoom_length(broadband, dt) * dt < 0.25
    # Pure noise shows no signal: the default length.
    assert np.isnan(signal_frequency_hz(_noisy(np.zeros(4000), 1.0, 4), dt))


def test_the_zoom_sits_where_the_signal_moves_most():
    values = _noisy(np.zeros(10_000), 0.1, 5)
    values[6000:6400] += 20.0 * np.sin(np.linspace(0, 8 * np.pi, 400))
    window = busiest_window(values, 300)
    assert window.start >= 6000 and window.stop <= 6400


def _figure(count, ref=True, spike=None):
    dt = 2e-3
    time = EPOCH + np.arange(count) * dt
    gas = 100.0 + 30.0 * np.sin(2 * np.pi * 7.0 * (time - EPOCH))
    tc1, tc2 = _noisy(gas - 5.0, 0.3, 6), _noisy(gas - 10.0, 0.3, 7)
    estimate = _noisy(gas, 0.5, 8)[:-1]
    if spike is not None:
        estimate[spike] = 900.0
    return reconstruction_figure(
        time,
        tc1,
        tc2,
        estimate,
        ref=gas[:-1] if ref else None,
        std=np.full(count - 1, 0.5),
        title="rec",
    )


def test_the_picture_has_the_whole_record_a_zoom_and_their_errors_on_time_from_the_start():
    figure = _figure(5000)
    whole, zoom, whole_error, zoom_error = figure.axes[:4]
    figure.canvas.draw()
    for ax in (whole, zoom, whole_error, zoom_error):
        assert ax.xaxis.get_major_formatter().get_offset() == ""  # no "+1.7e9"
    assert whole.get_xlim()[0] == pytest.approx(0.0, abs=0.6)
    assert whole.get_xlim()[1] == pytest.approx(10.0, abs=0.6)
    shown = np.diff(zoom.get_xlim())[0]
    assert 0.5 < shown < 1.0  # five periods of 7 Hz
    labels = figure.legends[0].get_texts()
    texts = [text.get_text() for text in labels]
    for name in ("tc1", "tc2", "gas (reconstructed)", "ref", "gas ± 2σ", "zoom", "± 2σ"):
        assert name in texts
    error = next(text for text in texts if text.startswith("gas − ref"))
    assert "rms over the record 0.5" in error
    assert "2023" in whole_error.get_xlabel() and "UTC" in whole_error.get_xlabel()


def test_without_a_reference_the_error_panel_is_the_sensors_disagreement():
    figure = _figure(3000, ref=False)
    texts = [text.get_text() for text in figure.legends[0].get_texts()]
    assert "ref" not in texts
    assert any(text.startswith("tc1 − tc2") for text in texts)


def test_a_single_bad_sample_of_a_long_record_still_shows_in_the_whole_record():
    # 60 000 samples are drawn as a min..max envelope, not thinned by a stride.
    figure = _figure(60_001, spike=31_337)
    whole = figure.axes[0]
    assert whole.get_ylim()[1] > 900.0


@pytest.mark.slow
def test_reconstruct_png_is_written_from_the_cli(tmp_path, capsys):
    dt = 2e-3
    time = np.arange(3000) * dt
    gas = 100.0 + 30.0 * np.sin(2 * np.pi * 3.0 * time)
    data = tmp_path / "run.csv"
    tau1, tau2 = 0.02, 0.08
    tc1, tc2 = np.empty_like(gas), np.empty_like(gas)
    tc1[0] = tc2[0] = gas[0]
    for k in range(1, gas.size):
        tc1[k] = tc1[k - 1] + dt / tau1 * (gas[k - 1] - tc1[k - 1])
        tc2[k] = tc2[k - 1] + dt / tau2 * (gas[k - 1] - tc2[k - 1])
    write_csv(data, time, _noisy(tc1, 0.05, 9), _noisy(tc2, 0.05, 10), gas)
    png = tmp_path / "gas.png"
    assert (
        main(["reconstruct", str(data), "-o", str(tmp_path / "gas.csv"), "--png", str(png)]) == 0
    )
    assert f"wrote {png}" in capsys.readouterr().out
    assert png.stat().st_size > 10_000


def test_the_compensated_picture_reads_the_reference_half_a_sample_on(monkeypatch, tmp_path):
    # The compensated path's e_Tg reads the reference half a sample on (element k is the gas
    # over [t_k, t_k+1)); its picture must compare the same way, or a 100 Hz signal at 500 Hz
    # shows a 2 degC "error" that is only the half-sample offset.
    import argparse

    import tcomp_core.plots
    from tcomp_core.cli.reconstruct import _plot
    from tcomp_core.io import Record

    seen = {}

    def capture(*args, **kwargs):
        seen.update(kwargs)
        return tmp_path / "x.png"

    monkeypatch.setattr(tcomp_core.plots, "plot_reconstruction", capture)
    time = np.arange(200) * 0.01
    ramp = 10.0 * time
    record = Record(time=time, tc1=ramp, tc2=ramp, ref=ramp, source="ramp", dt=0.01)
    args = argparse.Namespace(png=tmp_path / "x.png", data="ramp")
    gas = ramp[:-1] + 0.05
    _plot(args, record, gas, ramp[:-1], np.ones(199), half_sample_on=True)
    assert seen["ref_label"] == "ref half a sample on"
    assert np.allclose(seen["ref"][20:-20], gas[20:-20])
    _plot(args, record, gas, ramp[:-1], np.ones(199))
    assert seen["ref_label"] == "ref"
    assert np.allclose(seen["ref"], ramp[:-1])
