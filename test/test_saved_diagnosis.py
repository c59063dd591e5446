"""``--effects FILE.json``: the effects a saved diagnosis found, read back, and every way the
file can be wrong named (the round trip through ``tcomp diagnose --json`` is checked in
test_diagnose.py and test_diagnose_windows.py, and end to end by ``make demo``'s test)."""

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tcomp_core.cli import build_parser, main
from tcomp_core.cli.common import compensate_effects
from tcomp_core.diagnose.saved import (
    effects_of_diagnosis,
    read_diagnosis_effects,
    saved_diagnosis_effects,
)
from tcomp_core.effects import EFFECT_NAMES
from tcomp_core.errors import DataError
from tcomp_core.online import OnlineConfig
from tcomp_core.process import ProcessConfig

#: JSON values, effect names among the strings so that some documents are diagnoses.
JSON = st.recursive(
    st.none() | st.booleans() | st.floats() | st.sampled_from([*EFFECT_NAMES, "none"]) | st.text(),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner),
    max_leaves=12,
)
#: Documents shaped like a diagnosis at the keys the reader looks at, their values anything.
DOCUMENTS = st.fixed_dictionaries(
    {},
    optional={
        "final": st.fixed_dictionaries({}, optional={"effects": JSON}) | JSON,
        "verdict": st.sampled_from([*EFFECT_NAMES, "none", "unexplained"]) | JSON,
        "windows": st.lists(
            st.fixed_dictionaries(
                {}, optional={"verdict": st.sampled_from(EFFECT_NAMES) | JSON, "effects": JSON}
            )
            | JSON,
            max_size=3,
        )
        | JSON,
    },
)


def _window(verdict, effects):
    return {"index": 0, "verdict": verdict, "effects": effects}


def test_the_final_models_effects_are_read_in_their_order():
    document = {"verdict": "delay", "final": {"effects": ["delay", "calibration"]}}
    assert effects_of_diagnosis(document) == ("delay", "calibration")
    assert effects_of_diagnosis({"verdict": "none", "final": {"effects": []}}) == ()


def test_a_diagnosis_in_windows_gives_the_effects_of_a_window_with_the_whole_verdict():
    windows = [_window("none", []), _window("conduction", ["conduction"]), _window(None, [])]
    assert effects_of_diagnosis({"verdict": "conduction", "windows": windows}) == ("conduction",)
    assert effects_of_diagnosis({"verdict": "none", "windows": windows}) == ()
    with pytest.raises(ValueError, match="no window gives the whole record's verdict 'delay'"):
        effects_of_diagnosis({"verdict": "delay", "windows": windows})


def test_a_diagnosis_that_ended_unexplained_is_refused_with_its_residual():
    said = "the final model (first order) leaves 37 % against a noise floor of 1 %"
    whole = {"verdict": "unexplained", "final": {"effects": []}, "unexplained": said}
    windows = {"verdict": "unexplained", "windows": [_window("unexplained", [])]}
    for document in (whole, windows):
        with pytest.raises(ValueError, match=r"ended 'unexplained'.*--effects auto"):
            effects_of_diagnosis(document)
    with pytest.raises(ValueError) as raised:
        effects_of_diagnosis(whole)
    assert f"(its residual: {said})" in str(raised.value)
    # Effects found and some residual left: the found effects are physics to compensate with.
    partial = {"verdict": "delay", "final": {"effects": ["delay"]}, "unexplained": said}
    assert effects_of_diagnosis(partial) == ("delay",)
    votes = [_window("unexplained", []), _window("delay", ["delay"])]
    assert effects_of_diagnosis({"verdict": "delay", "windows": votes}) == ("delay",)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('{"final": {"effects": ["smoke"]}}', "unknown effect 'smoke'"),
        ('{"final": {"effects": "conduction"}}', "final.effects is 'conduction', not a list"),
        ('{"verdict": "x", "windows": [{"verdict": "x", "effects": [1]}]}', r"windows\[0\]"),
        ('{"tau1": 0.02}', "no diagnosis in it"),
        ("[1, 2]", "a JSON object is expected"),
        ("{not json", "not a diagnosis written as JSON"),
    ],
)
def test_a_bad_diagnosis_file_is_named_with_what_is_wrong(tmp_path, text, message):
    path = tmp_path / "diagnosis.json"
    path.write_text(text)
    with pytest.raises(DataError, match=message) as raised:
        read_diagnosis_effects(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_a_missing_file_is_an_error_naming_it(tmp_path):
    with pytest.raises(DataError, match=r"nope\.json: no such diagnosis file"):
        read_diagnosis_effects(tmp_path / "nope.json")


def test_the_option_resolves_a_file_to_names_and_leaves_other_values_alone(tmp_path, capsys):
    path = tmp_path / "Probe_A.JSON"
    path.write_text(json.dumps({"final": {"effects": ["radiation", "delay"]}}))
    assert compensate_effects(str(path)) == "radiation,delay"
    assert f"--effects {path}: radiation,delay (the final model" in capsys.readouterr().out
    path.write_text(json.dumps({"final": {"effects": []}}))
    assert compensate_effects(str(path)) == "none"
    for value in ("auto", "none", "conduction,delay", ""):
        assert compensate_effects(value) == value


def test_fit_takes_the_effects_of_a_saved_diagnosis_and_names_a_bad_one(tmp_path, capsys):
    found, data = tmp_path / "found.json", tmp_path / "run.csv"
    found.write_text(json.dumps({"final": {"effects": ["radiation", "delay"]}}))
    args = build_parser().parse_args(["fit", str(data), "--effects", str(found)])
    assert args.effects == ["radiation", "delay"]
    found.write_text(json.dumps({"final": {"effects": ["smoke"]}}))
    with pytest.raises(SystemExit):
        main(["fit", str(data), "--effects", str(found)])
    assert f"{found}: unknown effect 'smoke'" in capsys.readouterr().err


def test_the_engines_config_reads_the_file_once_into_names(tmp_path):
    path = tmp_path / "found.json"
    path.write_text(json.dumps({"final": {"effects": ["velocity"]}}))
    config = OnlineConfig(effects=f" {path} ")
    assert config.effects == "velocity" and config.requested_effects == ("velocity",)
    path.unlink()  # the engine holds the names, not the file
    assert config.requested_effects == ("velocity",)
    assert OnlineConfig.from_parameters({"effects": "auto"}).requested_effects is None
    with pytest.raises(DataError, match="no such diagnosis file"):
        OnlineConfig.from_parameters({"effects": str(path)})
    assert saved_diagnosis_effects("delay, calibration") == "delay, calibration"
    path.write_text(json.dumps({"final": {"effects": ["delay"]}}))
    assert ProcessConfig(effects=str(path)).effects == "delay"  # process() through the API


def test_process_and_reconstruct_refuse_a_bad_file_before_writing_anything(tmp_path, capsys):
    data = tmp_path / "run.csv"
    data.write_text("time,tc1,tc2\n0,1,1\n0.1,1,1\n")
    bad = tmp_path / "found.json"
    bad.write_text('{"final": {"effects": ["smoke"]}}')
    for verb, output in (("process", tmp_path / "out_bag"), ("reconstruct", tmp_path / "g.csv")):
        assert main([verb, str(data), "-o", str(output), "--effects", str(bad)]) == 1
        assert f"{bad}: unknown effect 'smoke'" in capsys.readouterr().err
        assert not output.exists()


@settings(derandomize=True, max_examples=300, deadline=None)
@given(st.one_of(DOCUMENTS.map(json.dumps), JSON.map(json.dumps), st.binary(max_size=64)))
def test_any_file_gives_known_effect_names_or_a_data_error(tmp_path_factory, content):
    path = tmp_path_factory.mktemp("saved") / "diagnosis.json"
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    try:
        found = read_diagnosis_effects(path)
    except DataError as error:
        assert str(error).startswith(f"{path}: ")
    else:
        assert json.loads(content).get("verdict") != "unexplained"
        assert isinstance(found, tuple)
        assert all(name in EFFECT_NAMES for name in found)
        assert len(set(found)) == len(found)
