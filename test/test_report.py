"""The HTML report: one self-contained page, every section present, all text escaped."""

from __future__ import annotations

import re
from dataclasses import replace
from html import escape

import numpy as np
import pytest
from scipy import signal

from tcomp_core.diagnose.residuals import analyse_failure
from tcomp_core.diagnose.result import Diagnosis, ModelFit, Suspect
from tcomp_core.effects import EFFECT_NAMES
from tcomp_core.fit import simulate_tc2_from_tc1
from tcomp_core.report import write_report
from tcomp_core.simulate import simulate_pair

DT = 0.002
HOSTILE = "<script>alert('x')</script>"
STAIRCASE = (12.34, 5.678, 4.321)


def model_fit(pair, effects, tau2, error_pct):
    a1, a2 = np.exp(-DT / 0.03), np.exp(-DT / tau2)
    return ModelFit(
        effects=tuple(effects),
        params={"tau1": 0.03, "tau2": tau2},
        tau1=0.03,
        tau2=tau2,
        error_pct=error_pct,
        raw_error_pct=error_pct + 1.0,
        noise_floor_pct=1.5,
        train_error_pct=0.9 * error_pct,
        block_errors_pct=np.full(4, error_pct),
        predicted=simulate_tc2_from_tc1(pair.tc1, pair.tc2[0], a1, a2),
        gas1=pair.gas + 0.01,
        gas2=pair.gas - 0.01,
        n_params=2 + len(effects),
    )


def suspect(name, error_pct, fit=None):
    return Suspect(
        effect=name,
        error_pct=error_pct,
        evidence=1.0 - error_pct / STAIRCASE[0],
        signature=f"signature of {name} & <friends>",
        significant=fit is not None,
        fit=fit,
    )


def make_diagnosis(source=HOSTILE):
    pair = simulate_pair("multisine", tau1=0.03, tau2=0.12, dt=DT, duration=4.0, noise_percent=1)
    n = pair.time.size
    validation = (np.arange(n) // 200) % 2 == 1
    base = model_fit(pair, (), 0.1, STAIRCASE[0])
    steps = [
        base,
        model_fit(pair, ("delay",), 0.11, STAIRCASE[1]),
        model_fit(pair, ("delay", "radiation"), 0.12, STAIRCASE[2]),
    ]
    sos = signal.butter(4, 20.0, output="sos", fs=1 / DT)
    failure = analyse_failure(
        pair.time,
        pair.tc1,
        pair.tc2,
        signal.sosfiltfilt(sos, base.predicted),
        signal.sosfiltfilt(sos, pair.tc2),
        pair.tc2 - base.predicted,
        dt=DT,
        slow=2,
        mask=validation & (np.arange(n) > 100),
    )
    others = [name for name in EFFECT_NAMES if name != "delay"]
    first = [suspect("delay", STAIRCASE[1], steps[1])] + [
        suspect(name, 11.0 + k) for k, name in enumerate(others)
    ]
    second = [suspect("radiation", STAIRCASE[2], steps[2]), suspect("conduction", 5.5)]
    return Diagnosis(
        source=source,
        time=pair.time,
        tc1=pair.tc1,
        tc2=pair.tc2,
        ref=pair.gas,
        dt=DT,
        slow=2,
        validation=validation,
        eval_cutoff_hz=20.0,
        sigma1=0.05,
        sigma2=0.05,
        phi=1.0,
        base=base,
        failure=failure,
        suspects=first,
        steps=steps,
        rounds=[first, second],
        verdict="delay",
        final=steps[-1],
        ref_error_pct={"gas1": 3.5, "gas2": 7.25, "fused": 3.0},
        notes=[f"a note with {HOSTILE}"],
    )


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    diagnosis = make_diagnosis()
    directory = tmp_path_factory.mktemp("report") / "new" / "dir"
    path = write_report(diagnosis, directory)
    assert path == directory / "index.html"
    return diagnosis, path


@pytest.mark.slow
def test_report_is_one_self_contained_page(report):
    diagnosis, path = report
    html = path.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>") and html.rstrip().endswith("</html>")
    assert html.count("<section>") == html.count("</section>") == 8
    assert "Verdict: delay" in html
    for name in EFFECT_NAMES:
        assert f"<td>{name}</td>" in html
    for value in STAIRCASE:
        assert f">{value:.4g}<" in html
    for finding in diagnosis.failure.findings:
        assert escape(finding) in html
    sources = re.findall(r'src="([^"]*)"', html)
    assert len(sources) == 5
    assert all(s.startswith("data:image/png;base64,") for s in sources)
    text = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "", html)
    assert "http" not in text
    assert 'src="file' not in text and "<link" not in text
    assert path.stat().st_size < 3_000_000


def test_report_escapes_hostile_text(report):
    html = report[1].read_text(encoding="utf-8")
    assert "<script" not in html
    assert "&lt;script&gt;" in html
    assert "&amp; &lt;friends&gt;" in html
    assert "<friends>" not in html


@pytest.mark.slow
def test_report_without_effects_or_reference(tmp_path):
    diagnosis = make_diagnosis(source="plain.csv")
    bare = replace(
        diagnosis,
        ref=None,
        steps=[diagnosis.base],
        rounds=[],
        suspects=[],
        verdict="none",
        final=diagnosis.base,
        ref_error_pct={},
        notes=[],
    )
    html = write_report(bare, tmp_path / "report").read_text(encoding="utf-8")
    assert "Verdict: none" in html
    assert "No effect was tried." in html
    assert html.count("data:image/png;base64,") == 5
