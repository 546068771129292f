"""Uncertainty campaigns: the draws' design, the band, the rank-correlation table, the command."""

import json
import math

import numpy as np
import pytest
import yaml

from isp_twin.cli import main
from isp_twin.experiments.rig import load_rig
from isp_twin.experiments.scenario import load_scenario
from isp_twin.experiments.sweep.design import scenario_of
from isp_twin.experiments.uncertainty import (
    Band,
    OatRow,
    UncertaintyResult,
    oat_runs,
    rig_knob_ranges,
    run_uncertainty,
    sensitivity,
    uncertainty_runs,
)

# A short closed loop (yaw 0.5 Hz, metrics over the last 0.4 s): ~50 ms a run.
SHORT = {
    "name": "short",
    "duration_s": 2.4,
    "turntable": {"table_yaw": {"rate_amplitude_deg_s": math.pi, "freq_hz": 0.5}},
}


@pytest.fixture()
def short(tmp_path):
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(SHORT))
    return load_scenario(path)


def _get(raw, path):
    for part in path.split("."):
        raw = raw[part]
    return raw


def _knobs(scenario):
    return rig_knob_ranges(load_rig(scenario.rig_path))


def test_the_rig_files_ranged_knobs_are_the_draws_inputs(short):
    rig = load_rig(short.rig_path)
    knobs = {k.name: k for k in _knobs(short)}
    assert set(knobs) == {n for n, k in rig.knobs.items() if k.range is not None}
    for name, k in knobs.items():
        assert (k.low, k.high) == tuple(rig.knobs[name].range)
        assert k.keys == tuple(rig.knobs[name].keys)
    assert knobs["resolver_rate_window"].integer and not knobs["gyro_scale"].integer


def test_each_draw_sets_every_key_of_a_knob_inside_its_range_for_both_controllers(short):
    knobs = [k for k in _knobs(short) if k.applies({"follower": {"enabled": True}})]
    runs = uncertainty_runs(short, 8, 3, short.parameters_path, knobs)
    assert len(runs) == 16
    for d in range(8):
        pi, nfc = runs[2 * d], runs[2 * d + 1]
        assert (pi.knobs["label"], nfc.knobs["label"]) == ("PI", "PI+NFC")
        assert pi.parameter_draw == nfc.parameter_draw and pi.seed == nfc.seed == short.seed + d
        assert _get(pi.scenario_raw, "controller.inner_az.nfc.enabled") is False
        assert _get(nfc.scenario_raw, "controller.inner_az.nfc.enabled") is True
        for k in knobs:
            value = pi.knobs[k.name]
            assert k.low <= value <= k.high
            assert isinstance(value, int) == k.integer
            for key in k.keys:  # the value reaches the scenario the worker rebuilds
                assert _get(pi.scenario_raw, key) == pytest.approx(value)
                assert _get(nfc.scenario_raw, key) == pytest.approx(value)
        scenario_of(pi)  # the drawn scenario loads
    # draws differ from each other; the whole design repeats with the seed
    assert len({json.dumps(r.parameter_draw, sort_keys=True) for r in runs}) == 8
    assert len({r.knobs["gyro_scale"] for r in runs}) == 8
    again = uncertainty_runs(short, 8, 3, short.parameters_path, knobs)
    assert [r.key for r in again] == [r.key for r in runs]
    other = uncertainty_runs(short, 8, 4, short.parameters_path, knobs)
    assert not {r.key for r in other} & {r.key for r in runs}


def test_knobs_apply_only_where_their_condition_holds(short):
    by_name = {k.name: k for k in _knobs(short)}
    follower_on, held = {"follower": {"enabled": True}}, {"follower": {"enabled": False}}
    assert by_name["start_angle_held"].applies(held)
    assert not by_name["start_angle_held"].applies(follower_on)
    assert by_name["gyro_scale"].applies(held) and by_name["gyro_scale"].applies(follower_on)


def test_the_one_at_a_time_design_moves_one_knob_to_each_end_and_nothing_else(short):
    knobs = [k for k in _knobs(short) if k.name in ("gyro_noise", "notch_freq")]
    runs = oat_runs(short, short.parameters_path, knobs, seeds=[1, 2])
    assert len(runs) == (1 + 2 * len(knobs)) * 2 * 2
    nominal = {r.knobs["label"]: r.scenario_raw for r in runs if r.knobs["knob"] is None}
    for r in runs:
        if r.knobs["knob"] is None:
            continue
        k = next(k for k in knobs if k.name == r.knobs["knob"])
        expected = k.low if r.knobs["end"] == "low" else k.high
        raw, base = r.scenario_raw, nominal[r.knobs["label"]]
        for key in k.keys:
            assert _get(raw, key) == pytest.approx(expected)
        other = next(o for o in knobs if o is not k)
        for key in other.keys:
            assert _get(raw, key) == _get(base, key)
        assert r.parameter_draw is None


def test_the_band_is_the_central_90_percent():
    b = Band.of(np.arange(101.0))
    assert (b.mean, b.low, b.high) == pytest.approx((50.0, 5.0, 95.0))


def test_rank_correlation_finds_a_monotone_nonlinear_input_and_ignores_noise():
    rng = np.random.default_rng(0)
    n = 100
    strong, weak, idle = rng.uniform(0, 1, n), rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    y1 = np.exp(5 * strong) + 0.5 * rng.standard_normal(n)  # monotone, far from linear
    y2 = -weak + 0.3 * rng.standard_normal(n)
    y3 = rng.standard_normal(n)
    rows = sensitivity(
        {"idle": idle, "weak": weak, "strong": strong, "const": np.ones(n)}, (y1, y2, y3)
    )
    by = {r.name: r for r in rows}
    assert rows[0].name == "strong" and by["strong"].rho_pi > 0.95 and by["strong"].significant
    assert by["weak"].rho_nfc < -0.5 and by["weak"].significant
    assert not by["idle"].significant
    assert math.isnan(by["const"].rho_pi) and not by["const"].significant
    assert rows[-1].name == "const"
    # three draws can correlate perfectly by chance: never significant
    few = sensitivity({"x": np.arange(3.0)}, (np.arange(3.0),) * 3)
    assert few[0].rho_pi == pytest.approx(1.0) and not few[0].significant


def _result(reduction, paper=41.8, failed=0):
    row = OatRow("k", "-", 0.0, 1.0, (20.0, 20.0), (10.0, 10.0), reduction, failed)
    res = UncertaintyResult(
        "s", "inner_az", 0, {}, np.ones(2), np.ones(2), np.zeros(2), 2, 0, (), paper, (row,)
    )
    return res.oat_verdict(row)


def test_the_one_at_a_time_verdict_separates_a_lost_sign_from_a_miss_of_the_paper():
    assert _result((40.0, 45.0)) == "ok"
    assert _result((40.0, 25.0)) == "off"
    assert _result((40.0, -5.0)) == "sign lost"
    assert _result((40.0, 45.0), failed=1) == "sign lost"
    assert _result((10.0, 80.0), paper=None) == "ok"


def test_uncertainty_runs_reproducibly_and_reports_a_band_around_its_draws(short):
    knobs = [k for k in _knobs(short) if k.name in ("gyro_noise", "follower_kp")]
    a = run_uncertainty(short, 4, seed=5, knobs=knobs, oat=True, oat_seeds=1)
    b = run_uncertainty(short, 4, seed=5, knobs=knobs)
    assert a.failed == 0 and len(a.j_pi) == 4
    assert np.array_equal(a.j_pi, b.j_pi) and np.array_equal(a.j_nfc, b.j_nfc)
    assert np.allclose(a.reduction, 100 * (a.j_pi - a.j_nfc) / a.j_pi)
    # the plant's drawn parameters and the knobs are the sensitivity's inputs
    assert {"gyro_noise", "follower_kp", "inner_az R+ Ts"} <= set(a.inputs)
    assert [r.knob for r in a.oat] == ["gyro_noise", "follower_kp"]
    assert a.paper_reduction is None  # not a paper experiment


def test_the_command_writes_its_plot_and_json_and_refuses_bad_counts(short, tmp_path, capsys):
    png, js = tmp_path / "u.png", tmp_path / "u.json"
    argv = ["campaign", str(short.source), "--uncertainty", "3", "--jobs", "1"]
    assert main([*argv, "--plot", str(png), "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert "90 % band" in out and "sensitivity" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    doc = json.loads(js.read_text())
    assert len(doc["per_draw"]["J_PI"]) == 3 and doc["failed_draws"] == 0
    assert main([*argv[:3], "1", "--no-plot"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--uncertainty must be >= 2" in err
