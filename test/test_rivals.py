"""Issue 24: which explanations stand beside the one the diagnosis takes.

A rival effect the held-out blocks do not rule out joins the gas band. Campaign draw 3402
(conduction to lagging supports behind a mains line) took a calibration with tc2's gain at 0.83
where a conduction explained the held-out blocks as well; the calibration's τ put the gas
7.40 → 9.00 % off. What the rival would publish is part of what the data leave open (its move
in the band: test_compensation.py). An effect the default path accounts for itself (lines it
takes off, a noise ratio it measures) is named from that path's own finding, by the effect's
module. And no verdict rests on a last effect whose whole-record fit ends on a bound of its
physical range.
"""

import dataclasses

import numpy as np

from tcomp_core.diagnose.pipeline import Staircase, _refit_final, _rivals
from tcomp_core.diagnose.result import ModelFit, Suspect


def _fit(effects, raw, blocks, params=None, at_bound=()):
    return ModelFit(
        effects=tuple(effects),
        params={"tau1": 0.02, "tau2": 0.1, **(params or {})},
        tau1=0.02,
        tau2=0.1,
        error_pct=raw,
        raw_error_pct=raw,
        noise_floor_pct=0.1,
        train_error_pct=raw,
        block_errors_pct=np.asarray(blocks, dtype=float),
        predicted=np.zeros(3),
        gas1=np.zeros(3),
        gas2=np.zeros(3),
        n_params=2 + len(effects),
        at_bound=tuple(at_bound),
    )


def _suspect(fit, significant=True):
    return Suspect(
        effect=fit.effects[-1],
        error_pct=fit.error_pct,
        evidence=0.5,
        signature="",
        significant=significant,
        fit=fit,
    )


def test_rivals_are_the_last_rounds_significant_suspects_the_one_taken_does_not_beat_clearly():
    base = _fit((), 15.0, [15.0] * 5)
    first = _fit(("interference",), 1.66, [1.7, 1.6, 1.7, 1.6, 1.7])
    taken = _fit(("interference", "calibration"), 1.12, [1.1, 1.2, 1.1, 1.1, 1.2])
    close = _fit(("interference", "conduction"), 1.156, [1.2, 1.1, 1.2, 1.1, 1.1])
    beaten = _fit(("interference", "radiation"), 1.57, [1.6, 1.5, 1.6, 1.5, 1.6])
    weak = _fit(("interference", "delay"), 1.13, [1.1, 1.2, 1.1, 1.2, 1.1])
    rounds = [
        [_suspect(first), _suspect(_fit(("conduction",), 12.6, [12.6] * 5), False)],
        [_suspect(taken), _suspect(close), _suspect(beaten), _suspect(weak, significant=False)],
    ]
    staircase = Staircase([base, first, taken], rounds, [])
    assert _rivals(staircase) == [close]
    # The first round's conduction was no rival to the interference: not significant.
    assert _rivals(Staircase([base, first], rounds[:1], [])) == []
    assert _rivals(Staircase([base], [], [])) == []


def test_the_effects_the_default_path_accounts_for_are_named_from_its_own_findings():
    from tcomp_core.effects import EFFECTS
    from tcomp_core.effects.noise_ratio import NOISE_RATIO_FACTOR
    from tcomp_core.lines import ForeignLine

    def found(lines, phi):
        return {
            name for name, effect in EFFECTS.items() if effect().found_by_default_path(lines, phi)
        }

    line = [ForeignLine(frequency_hz=50.0, channel=2, amplitude_c=1.0)]
    assert found(line, 1.0) == {"interference"}
    assert found([], 1.0) == set()
    # Noise variances measured to differ beyond the factor, either way; within it, nothing.
    beyond = 1.05 * NOISE_RATIO_FACTOR
    assert found([], beyond) == found([], 1.0 / beyond) == {"noise_ratio"}
    assert found([], 0.95 * NOISE_RATIO_FACTOR) == found([], 1.0 / 1.9) == set()
    assert found(line, 6.5) == {"interference", "noise_ratio"}
    assert "phi = sigma1^2/sigma2^2 = 6.5" in EFFECTS["noise_ratio"]().found_by_default_path(
        [], 6.5
    )


class _WholeRecord:
    """An evaluator whose whole-record refits are given: effects -> the refit's fit."""

    def __init__(self, refits):
        self.refits = refits

    def refit_whole(self, fit, other_form, rivals):
        return self.refits[fit.effects]


def test_a_last_effect_whose_whole_record_fit_ends_on_a_physical_bound_is_dropped():
    # Campaign draw 3465: radiation taken on the estimation blocks, its wall at -72.85 degC
    # (200 K, its bound) once refitted on the whole record, and the verdict was radiation.
    base = _fit((), 5.0, [5.0] * 5)
    ordinary = _fit(("property",), 0.64, [0.6] * 5, {"property_exponent": 0.3})
    radiating = _fit(
        ("property", "radiation"), 0.5, [0.5] * 5, {"property_exponent": 0.3, "wall_c": 0.0}
    )
    on_bound = _fit(
        ("property", "radiation"),
        0.5,
        [0.5] * 5,
        {"property_exponent": 0.3, "wall_c": -72.85},
        at_bound=("wall_c",),
    )
    whole = {(): base, ("property",): ordinary, ("property", "radiation"): on_bound}
    rounds = [[_suspect(ordinary)], [_suspect(radiating)]]
    staircase = Staircase([base, ordinary, radiating], rounds, ["property"])
    final = _refit_final(_WholeRecord(whole), staircase)
    assert [step.effects for step in final.steps] == [(), ("property",)]
    assert final.steps[-1] is ordinary and final.expected == ["property"]
    assert "property+radiation was taken on the estimation blocks" in final.note
    assert "so radiation is dropped" in final.note
    assert "wall_c = -72.85" in final.note
    # Off its bound on the whole record, it stays.
    whole[("property", "radiation")] = radiating
    kept = _refit_final(_WholeRecord(whole), staircase)
    assert kept.steps[-1] is radiating and kept.note == ""
    # A τ already on its bound before the effect does not count against it.
    for_tau = _fit(("radiation",), 0.5, [0.5] * 5, {"wall_c": 0.0}, at_bound=("tau1",))
    base_on_bound = _fit((), 5.0, [5.0] * 5, at_bound=("tau1",))
    whole = {(): base_on_bound, ("radiation",): for_tau}
    steps = Staircase([base_on_bound, for_tau], [[_suspect(for_tau)]], [])
    assert _refit_final(_WholeRecord(whole), steps).steps[-1] is for_tau
    # Campaign draw 3503: the first effect's amplitude on its bound under the second, and
    # still there alone: both are dropped, down to the base model.
    line = {"interference_b1": 30.0}
    first = _fit(("interference",), 1.0, [1.0] * 5, line, at_bound=("interference_b1",))
    second = _fit(("interference", "property"), 0.9, [0.9] * 5, {**line, "property_exponent": 1})
    whole = {
        (): base,
        ("interference",): first,
        ("interference", "property"): dataclasses.replace(second, at_bound=("interference_b1",)),
    }
    rounds = [[_suspect(first)], [_suspect(second)]]
    final = _refit_final(_WholeRecord(whole), Staircase([base, first, second], rounds, []))
    assert [step.effects for step in final.steps] == [()]
    assert final.note.count("interference_b1 = 30") == 2
