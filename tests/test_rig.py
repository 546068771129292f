"""The rig file: the shipped paper rig, how scenarios use a rig, and what a bad rig file gets."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from isp_twin.errors import RigError
from isp_twin.experiments.paper import PAPER_CELLS
from isp_twin.experiments.rig import load_rig, parse_rig, resolve_rig
from isp_twin.experiments.scenario import Scenario, load_scenario, parse_scenario
from isp_twin.resources import resource_root

RIG_FILE = resource_root() / "models" / "rigs" / "paper_rig.yaml"

CLOSED = {
    "kind": "closed_loop",
    "duration_s": 0.06,
    "turntable": {"table_yaw": {"amplitude_deg": 3.0, "freq_hz": 1.0}},
    "metrics": {"skip_s": 0.01},
}


def _get(obj, key: str):
    for part in key.split("."):
        obj = getattr(obj, part)
    return obj


def test_the_paper_rig_is_the_default_and_loads():
    rig = load_rig(resolve_rig("paper_rig"))
    assert rig.name == "paper_rig"
    assert Scenario().rig == "paper_rig"
    assert rig.path == RIG_FILE


def test_every_unconditional_knob_equals_the_scenario_schema_default():
    """The scenario dataclass defaults (and so the exported JSON Schema) are the paper rig's."""
    rig = load_rig(RIG_FILE)
    bare = Scenario()
    for knob in rig.knobs.values():
        if knob.when:
            continue
        for key in knob.keys:
            assert _get(bare, key) == knob.value, (knob.name, key)


def test_every_setting_the_issue_lists_has_a_knob_with_provenance_and_range():
    rig = load_rig(RIG_FILE)
    keys = {k for knob in rig.knobs.values() for k in knob.keys}
    for key in (
        "gyro.scale_count_per_deg_s",
        "gyro.bandwidth_hz",
        "gyro.noise_deg_s",
        "resolver.rate_window",
        "controller.inner_az.pi_form",
        "controller.inner_az.notch.freq_hz",
        "controller.inner_az.bound_digits",
        "follower.kp_digit_per_deg",
        "follower.ki_digit_per_deg",
        "follower.kd_digit_per_deg_s",
        "follower.inner_az_center_deg",
        "follower.inner_el_center_deg",
        "initial_angles_deg.inner_az",
    ):
        assert key in keys, key
    for knob in rig.knobs.values():
        assert (knob.range is None) != (knob.choices is None), knob.name
        if knob.range is not None:
            assert knob.range[0] <= knob.value <= knob.range[1], knob.name
        if knob.provenance == "calibrated":
            assert knob.cells and set(knob.cells) <= set(PAPER_CELLS), knob.name


def test_only_the_gyro_scale_is_fitted_and_only_on_the_working_point_cell():
    rig = load_rig(RIG_FILE)
    assert [k.name for k in rig.fitted()] == ["gyro_scale"]
    assert rig.fitted_cells() == ("table4_1_6Hz_pi",)


def test_hand_chosen_settings_are_declared_calibrated_on_the_cells_that_shaped_them():
    """Issue 10: PI form, notch, follower gains, centres and the held start angle were
    chosen after looking at results; the rig says so."""
    rig = load_rig(RIG_FILE)
    for name in ("pi_form", "notch_freq", "follower_kp", "inner_az_center", "start_angle_held"):
        assert rig.knob(name).provenance == "calibrated", name
    assert "table5_pi_nfc" in rig.knob("notch_freq").cells
    assert "table6_pi_nfc" in rig.knob("follower_kd").cells
    assert "notch_freq" in rig.shaping("table5_pi_nfc")


def test_a_rig_value_fills_keys_the_scenario_leaves_unset(tmp_path):
    text = RIG_FILE.read_text().replace("    value: 70.0\n", "    value: 80.0\n", 1)
    (tmp_path / "my_rig.yaml").write_text(text)
    raw = dict(CLOSED, rig="my_rig.yaml")
    scenario = parse_scenario(raw, tmp_path / "s.yaml")
    assert scenario.gyro.scale_count_per_deg_s == 80.0
    own = dict(raw, gyro={"scale_count_per_deg_s": 70.0})
    assert parse_scenario(own, tmp_path / "s.yaml").gyro.scale_count_per_deg_s == 70.0


def test_a_knob_with_when_applies_only_to_matching_scenarios():
    held = parse_scenario(dict(CLOSED, follower={"enabled": False}))
    follows = parse_scenario(dict(CLOSED, follower={"enabled": True}))
    value = load_rig(RIG_FILE).knob("start_angle_held").value
    assert held.initial_angles_deg.inner_az == value != 0.0
    assert follows.initial_angles_deg.inner_az == 0.0


def test_the_shipped_scenarios_run_on_the_rig_values_they_do_not_override():
    rig = load_rig(RIG_FILE)
    tracking = load_scenario("tracking_0_5Hz")
    assert tracking.initial_angles_deg.inner_az == rig.knob("start_angle_held").value
    assert load_scenario("table4_0_5Hz_2pi").initial_angles_deg.inner_az == 0.0
    turbulence = load_scenario("turbulence_1_6Hz")
    assert turbulence.follower.inner_az_center_deg == rig.knob("inner_az_center").value


def test_a_scenario_round_trips_with_its_rig_values_explicit():
    from isp_twin.experiments.scenario import scenario_to_raw

    s = load_scenario("tracking_0_5Hz")
    again = parse_scenario(scenario_to_raw(s), s.source)
    assert dataclasses.replace(again, text="") == dataclasses.replace(s, text="")


GOOD = {
    "name": "r",
    "knobs": {
        "scale": {
            "value": 65.0,
            "unit": "count/(deg/s)",
            "keys": ["gyro.scale_count_per_deg_s"],
            "range": [40.0, 100.0],
            "provenance": "calibrated",
            "cells": ["table4_1_6Hz_pi"],
            "fit": {"cells": ["table4_1_6Hz_pi"], "values": [60.0, 70.0]},
            "note": "n",
        }
    },
}


def _bad(**edit):
    knob = dict(GOOD["knobs"]["scale"], **edit)
    return {"name": "r", "knobs": {"scale": knob}}


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        (_bad(value=120.0), "outside its plausible range"),
        (_bad(keys=["gyro.scale"]), "unknown scenario key 'scale'"),
        (_bad(cells=["table7"]), "unknown paper cell 'table7'"),
        (_bad(fit={"cells": ["table4_0_5Hz_pi"], "values": [60.0]}), "not listed in the knob"),
        (_bad(fit={"cells": ["table4_1_6Hz_pi"], "values": [1.0]}), "outside the range"),
        (_bad(provenance="assumption"), "only a calibrated knob"),
        (_bad(range=[100.0, 40.0]), "is above high"),
        (_bad(choices=["a"]), "either 'range'"),
        (_bad(value="x"), "expected a number"),
        ({"name": "r", "knobs": {}}, "knobs"),
        ({"name": "r", "knob": {}}, "unknown key (did you mean 'knobs'?)"),
    ],
)
def test_a_bad_rig_is_refused_naming_the_problem(raw, message):
    parse_rig(GOOD)  # the unedited rig is valid
    with pytest.raises(RigError, match=None) as info:
        parse_rig(raw, Path("r.yaml"))
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_run_json_names_the_rig_and_the_nfc_model(tmp_path):
    import json

    from isp_twin.cli import main

    scenario = tmp_path / "s.yaml"
    scenario.write_text(
        "kind: closed_loop\nduration_s: 0.06\nmetrics: {skip_s: 0.01}\n"
        "turntable:\n  table_yaw: {amplitude_deg: 3.0, freq_hz: 1.0}\n"
        "controller: {inner_az: {nfc: {enabled: true}}}\n"
    )
    out = tmp_path / "m.json"
    assert main(["run", str(scenario), "--no-recording", "--json", str(out)]) == 0
    payload = json.loads(out.read_text())
    assert payload["rig"] == "paper_rig"
    assert Path(payload["nfc_parameters"]).name == "twin_identified.yaml"
