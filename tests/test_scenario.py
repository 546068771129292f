"""Scenario schema: shipped files load, errors name the key path, schema export is current."""

import json
from pathlib import Path

import pytest

from isp_twin.errors import ResourceNotFound, ScenarioError
from isp_twin.experiments.scenario import (
    Scenario,
    load_scenario,
    parse_scenario,
    scenario_json_schema,
    scenario_json_schema_text,
)
from isp_twin.resources import resource_root
from isp_twin.units import DEG

SCENARIOS = resource_root() / "scenarios"
SHIPPED = sorted(SCENARIOS.glob("*.yaml"))
MOVING = {"turntable": {"table_yaw": {"rate_amplitude_deg_s": 3.14, "freq_hz": 0.5}}}


def test_there_are_shipped_scenarios():
    names = {p.stem for p in SHIPPED}
    assert {"turbulence_1_6Hz", "tracking_0_5Hz", "openloop_0_5Hz"} <= names
    assert len([n for n in names if n.startswith("table4_")]) == 6


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_every_shipped_scenario_loads_and_matches_the_schema_keys(path):
    import yaml

    scenario = load_scenario(path)
    assert scenario.name == path.stem
    assert scenario.parameters_path.is_file()
    schema = scenario_json_schema()

    def walk(raw, node, where):
        for key, value in raw.items():
            assert key in node["properties"], f"{where}{key} missing from the schema"
            sub = node["properties"][key]
            if isinstance(value, dict):
                walk(value, sub, f"{where}{key}.")

    walk(yaml.safe_load(path.read_text()), schema, "")


def test_exported_schema_file_is_up_to_date():
    assert (SCENARIOS / "scenario.schema.json").read_text() == scenario_json_schema_text()
    schema = json.loads(scenario_json_schema_text())
    assert schema["additionalProperties"] is False
    nfc = schema["properties"]["controller"]["properties"]["inner_az"]["properties"]["nfc"]
    assert nfc["properties"]["gamma"]["maximum"] == 1.0


def test_bare_name_is_found_from_any_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert load_scenario("turbulence_1_6Hz.yaml").name == "turbulence_1_6Hz"
    assert load_scenario("tracking_0_5Hz").name == "tracking_0_5Hz"


def test_unknown_key_names_the_path_and_the_nearest_key(tmp_path):
    path = tmp_path / "turbulence_1_6Hz.yaml"
    path.write_text(
        "turntable: {table_yaw: {rate_amplitude_deg_s: 3.14}}\n"
        "controller:\n  inner_az:\n    pi: {kpp: 3.0}\n"
    )
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    msg = str(err.value)
    assert "turbulence_1_6Hz.yaml: controller.inner_az.pi.kpp: unknown key" in msg
    assert "did you mean 'kp_digit_per_count'" in msg


@pytest.mark.parametrize(
    "raw, match",
    [
        ({"duration_s": -1.0}, r"duration_s: -1.0 out of range; must be > 0"),
        ({"controller": {"inner_az": {"nfc": {"gamma": 1.2}}}}, r"nfc.gamma: 1.2 out of range"),
        ({"controller": {"inner_el": {"notch": {"freq_hz": 600.0}}}}, r"notch.freq_hz.*Nyquist"),
        ({"kind": "openloop"}, r"kind: 'openloop' is not allowed \(did you mean 'open_loop'\?\)"),
        ({"seed": 1.5}, r"seed: expected an integer"),
        ({"gyro": {"noise_deg_s": "loud"}}, r"gyro.noise_deg_s: expected a number"),
        ({"follower": {"enabled": "yes"}}, r"follower.enabled: expected true or false"),
        ({"turntable": "fast"}, r"turntable: expected a mapping"),
    ],
)
def test_bad_values_are_rejected_with_the_key_path(raw, match):
    with pytest.raises(ScenarioError, match=match):
        parse_scenario({**MOVING, **raw}, "s.yaml")


def test_closed_loop_without_carrier_motion_is_rejected():
    with pytest.raises(ScenarioError, match="turntable: a closed-loop scenario needs"):
        parse_scenario({}, "s.yaml")


def test_duration_shorter_than_the_discarded_transient_is_rejected():
    motion = {"rate_amplitude_deg_s": 1.0, "freq_hz": 0.5}
    raw = {"duration_s": 1.0, "turntable": {"table_yaw": motion}}
    with pytest.raises(ScenarioError, match="metrics.skip_s"):
        parse_scenario(raw, "s.yaml")


def test_invalid_yaml_names_the_file_and_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("name: x\nturntable: [unclosed\n")
    with pytest.raises(ScenarioError, match=r"broken.yaml: line \d+ not valid YAML"):
        load_scenario(path)


def test_missing_file_and_missing_parameter_file(tmp_path):
    with pytest.raises(ResourceNotFound, match="no such scenario"):
        load_scenario(tmp_path / "nope.yaml")
    path = tmp_path / "s.yaml"
    path.write_text("parameters: nowhere.yaml\nturntable: {table_yaw: {rate_amplitude_deg_s: 1}}\n")
    with pytest.raises(ResourceNotFound, match="parameters: file 'nowhere.yaml' not found"):
        _ = load_scenario(path).parameters_path


def test_parameters_path_is_relative_to_the_scenario_file(tmp_path):
    (tmp_path / "mine.yaml").write_text("x")
    path = tmp_path / "s.yaml"
    path.write_text("parameters: mine.yaml\nturntable: {table_yaw: {rate_amplitude_deg_s: 1}}\n")
    assert load_scenario(path).parameters_path == tmp_path / "mine.yaml"


def test_amplitude_in_degrees_converts_to_the_paper_rate():
    s = load_scenario("turbulence_1_6Hz")
    # 3 deg at 1/6 Hz is pi deg/s (Sect. 4.2)
    for motion in s.turntable.motions().values():
        assert motion.rate_amplitude == pytest.approx(3.141592653589793 * DEG)
    assert s.skip_s == pytest.approx(6.0)


def test_paper_gains_and_nfc_switch():
    s = load_scenario("turbulence_1_6Hz")
    az = s.controller.inner_az
    assert az.nfc.enabled and az.nfc.gamma == 0.95
    assert (az.gains.kp_digit_per_count, az.gains.ki_digit_per_count) == (3.0, 0.15)
    pi = s.with_nfc(False).controller.inner_az
    assert (pi.gains.kp_digit_per_count, pi.gains.ki_digit_per_count) == (3.568, 0.0714)


def test_open_loop_attributes_for_the_open_loop_runner():
    s = load_scenario("openloop_0_5Hz")
    assert s.kind == "open_loop" and s.duration_s == 6.0
    assert s.open_loop.axis == "inner_az"
    c = s.open_loop.command
    assert (c.amplitude_digits, c.freq_hz, c.offset_digits) == (950.0, 0.5, 0.0)
    assert s.open_loop.initial_angle_deg == 0.0
    assert isinstance(s.parameters_path, Path) and s.parameters_path.is_file()


def test_scenarios_compare_by_content():
    a = parse_scenario(MOVING, "a.yaml")
    b = parse_scenario(MOVING, "a.yaml")
    assert a == b and isinstance(a, Scenario)
