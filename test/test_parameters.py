"""One parameter schema: the shipped YAML, the engine's config and ``tcomp process`` follow it.

The YAML file is read by rclpy's own parameter-file reader (what ``--params-file`` uses), so
the test sees the values a node started with it would get.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from tcomp_core import parameters
from tcomp_core.cli import build_parser
from tcomp_core.online import OnlineConfig
from tcomp_core.online.config import ENGINE_PARAMETERS
from tcomp_core.parameters import PARAMETERS, yaml_text

SHIPPED = Path(__file__).resolve().parents[1] / "config" / "compensator.yaml"


def _yaml_values(path: Path) -> dict[str, object]:
    from rclpy.parameter import Parameter, parameter_dict_from_yaml_file

    found = parameter_dict_from_yaml_file(str(path), use_wildcard=True)
    return {name: Parameter.from_parameter_msg(msg).value for name, msg in found.items()}


def test_the_shipped_yaml_holds_every_parameter_at_its_declared_default():
    values = _yaml_values(SHIPPED)
    declared = {spec.name: spec.default for spec in PARAMETERS}
    assert set(values) == set(declared), "parameters missing from or unknown to the YAML file"
    for name, default in declared.items():
        assert values[name] == default, name
        assert type(values[name]) is type(default), name
    assert SHIPPED.read_text() == yaml_text()  # written from the schema, notes included


def test_a_yaml_file_that_disagrees_is_caught(tmp_path):
    # The check above can fail: a file with an old default and a parameter missing.
    lines = [
        line.replace("method: ml-eiv", "method: beta-gtls")
        for line in yaml_text().splitlines()
        if not line.strip().startswith("discontinuity_s")
    ]
    stale = tmp_path / "stale.yaml"
    stale.write_text("\n".join(lines) + "\n")
    values = _yaml_values(stale)
    assert "discontinuity_s" not in values
    assert values["method"] != parameters.default("method")


def test_the_engine_config_takes_its_defaults_and_ranges_from_the_schema():
    config = OnlineConfig()
    for name in ENGINE_PARAMETERS:
        assert getattr(config, name) == parameters.default(name), name
    fields = {field.name for field in dataclasses.fields(OnlineConfig)}
    assert set(ENGINE_PARAMETERS) <= fields
    assert fields - set(ENGINE_PARAMETERS) == {"postfilter_order", "gap_factor"}
    for spec in PARAMETERS:
        if spec.scope != "engine":
            continue
        if spec.high is not None:
            too_high = spec.high * 2 + 1
            with pytest.raises(ValueError, match=spec.name):
                OnlineConfig(**{spec.name: type(spec.default)(too_high)})
        if spec.choices:
            with pytest.raises(ValueError, match=spec.name):
                OnlineConfig(**{spec.name: "no-such-choice"})


def test_the_defaults_are_the_best_gas_for_a_stream():
    assert parameters.default("reconstruction") == "kalman"
    assert parameters.default("signal_model") == "auto"
    assert parameters.default("method") == "ml-eiv"


def test_tcomp_process_options_default_to_the_node_parameters():
    parser = build_parser()
    args = parser.parse_args(["process", "in.csv", "-o", "out.csv"])
    from tcomp_core.cli.process import ENGINE_OPTIONS, process_config

    for name in ENGINE_OPTIONS:
        assert getattr(args, name) == parameters.default(name), name
    config = process_config(args)
    assert config.online == OnlineConfig()
