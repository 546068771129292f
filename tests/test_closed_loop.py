"""The closed-loop runner on the MuJoCo twin: signals, reproducibility, failures."""

import dataclasses

import numpy as np
import pytest

from isp_twin.errors import ScenarioError, SimulationDiverged
from isp_twin.experiments.closed_loop import run_scenario, table_angles
from isp_twin.experiments.scenario import Motion, load_scenario, parse_scenario
from isp_twin.units import DEG

SHORT = {
    "duration_s": 2.5,
    "turntable": {"table_yaw": {"rate_amplitude_deg_s": 3.141592653589793, "freq_hz": 0.5}},
}


@pytest.fixture(scope="module")
def short_run():
    return run_scenario(parse_scenario(SHORT, "short.yaml"))


def test_table_angle_is_the_integral_of_the_rate():
    t = np.arange(0, 6, 1e-3)
    for waveform in ("sine", "cosine"):
        m = Motion(rate_amplitude_deg_s=2.0, freq_hz=0.5, phase_deg=30.0, waveform=waveform)
        angle = table_angles(m, t)
        rate = np.gradient(angle, t)
        fn = np.sin if waveform == "sine" else np.cos
        expected = 2.0 * DEG * fn(2 * np.pi * 0.5 * t + np.radians(30.0))
        assert angle[0] == 0.0
        assert np.max(np.abs(rate[1:-1] - expected[1:-1])) < 1e-5


def test_signals_have_the_documented_names_and_lengths(short_run):
    n = len(short_run.t)
    assert n == 2501 and short_run.t[1] == pytest.approx(1e-3)
    for axis in ("inner_az", "inner_el"):
        for sig in (
            "omega_carrier",
            "omega_inertial",
            "omega_relative",
            "gyro",
            "command",
            "friction",
            "nfc",
            "regime",
        ):
            assert short_run.signals[f"{axis}/{sig}"].shape == (n,)
    for axis in ("outer_az", "outer_el"):
        assert short_run.signals[f"{axis}/follow_error"].shape == (n,)
    assert set(short_run.joint_angles) == {
        "table_yaw",
        "table_pitch",
        "table_roll",
        "outer_az",
        "outer_el",
        "inner_az",
        "inner_el",
    }
    assert not short_run.interrupted
    assert short_run.scenario_text == "" and "paper_table2" in short_run.parameters_file


def test_the_loop_isolates_the_carrier(short_run):
    m = short_run.metrics["inner_az"]
    assert m["isolation_percent"] < 40.0
    # the pitch and roll stand still, so the elevation has no J
    assert "inner_el" not in short_run.metrics


def test_without_feedback_the_gimbal_rides_the_base_and_the_pi_loop_isolates_it():
    held = {**SHORT, "follower": {"enabled": False}}
    no_loop = {**held, "controller": {"inner_az": {"pi": {"kp_digit_per_count": 0.0}}}}
    # Static friction holds an undriven gimbal on its base: omega_1 = omega, J = 100 %.
    j_open = run_scenario(parse_scenario(no_loop, "s.yaml")).metrics["inner_az"]
    assert j_open["isolation_percent"] == pytest.approx(100.0, abs=0.5)
    j_pi = run_scenario(parse_scenario(held, "s.yaml")).metrics["inner_az"]
    assert j_pi["isolation_percent"] < j_open["isolation_percent"] / 3


def test_gyro_reads_the_inertial_rate_at_its_scale(short_run):
    scenario = parse_scenario(SHORT, "short.yaml")
    g = scenario.gyro
    window = short_run.t >= 1.0
    gyro = short_run.signals["inner_az/gyro"][window]
    w1 = short_run.signals["inner_az/omega_inertial"][window]
    # slope 1: the counts are converted back with the same scale
    assert np.dot(gyro, w1) / np.dot(w1, w1) == pytest.approx(1.0, abs=0.03)
    # what is left is the noise and the count quantum (lag aside), 3 sigma
    sigma = np.hypot(g.noise_deg_s, 1.0 / g.scale_count_per_deg_s / np.sqrt(12.0)) * DEG
    assert np.sqrt(np.mean((gyro - w1) ** 2)) < 3 * sigma


@pytest.mark.parametrize("center_deg", [-1.5, 1.5])
def test_the_follower_holds_the_inner_gimbal_near_its_centre(center_deg):
    raw = {**SHORT, "duration_s": 4.0, "follower": {"inner_az_center_deg": center_deg}}
    result = run_scenario(parse_scenario(raw, "short.yaml"))
    angle = result.joint_angles["inner_az"][result.t >= 2.0]
    assert np.mean(angle) == pytest.approx(center_deg * DEG, abs=0.3 * DEG)


def test_gyro_signal_is_the_quantised_noisy_reading(short_run):
    s = short_run.signals
    scenario = parse_scenario(SHORT, "short.yaml")
    quantum = DEG / scenario.gyro.scale_count_per_deg_s
    counts = s["inner_az/gyro"] / quantum
    assert np.allclose(counts, np.round(counts), atol=1e-6)
    assert np.any(s["inner_az/gyro"] != s["inner_az/omega_inertial"])


def test_same_seed_same_numbers_other_seed_other_numbers():
    scenario = parse_scenario({**SHORT, "duration_s": 2.2}, "short.yaml")
    a = run_scenario(scenario, seed=4)
    b = run_scenario(scenario, seed=4)
    c = run_scenario(scenario, seed=5)
    assert a.metrics == b.metrics
    assert np.array_equal(a.signals["inner_az/gyro"], b.signals["inner_az/gyro"])
    assert not np.array_equal(a.signals["inner_az/gyro"], c.signals["inner_az/gyro"])


def test_decimation_thins_the_record_but_not_the_metrics(short_run):
    raw = {**SHORT, "record": {"decimation": 10}}
    thin = run_scenario(parse_scenario(raw, "short.yaml"))
    assert thin.metrics == short_run.metrics
    assert len(thin.t) == 251 and thin.t[1] == pytest.approx(0.01)
    assert np.array_equal(
        thin.signals["inner_az/command"], short_run.signals["inner_az/command"][::10]
    )


def test_absurd_gains_stop_with_the_time_and_signal_named():
    raw = {
        **SHORT,
        "controller": {"inner_az": {"pi": {"kp_digit_per_count": 1e6}, "bound_digits": 1e9}},
    }
    with pytest.raises(SimulationDiverged, match=r"diverged at t=\d+\.\d+ s: inner_az"):
        run_scenario(parse_scenario(raw, "absurd.yaml"))


def test_a_loop_pinned_at_its_bound_stops_as_unstable():
    raw = {**SHORT, "controller": {"inner_az": {"pi": {"kp_digit_per_count": 1000.0}}}}
    with pytest.raises(
        SimulationDiverged,
        match=r"unstable at t=\d+\.\d+ s: inner_az/command has been at its bound",
    ):
        run_scenario(parse_scenario(raw, "absurd.yaml"))


def test_ctrl_c_returns_the_partial_run_marked_interrupted():
    calls = []

    def progress(t, duration):
        calls.append(t)
        if t >= 1.0:
            raise KeyboardInterrupt

    result = run_scenario(parse_scenario(SHORT, "short.yaml"), on_progress=progress)
    assert result.interrupted
    assert 1000 <= len(result.t) < 2501
    assert all(len(v) == len(result.t) for v in result.signals.values())
    assert np.all(np.isfinite(result.signals["inner_az/omega_inertial"]))


def test_open_loop_scenarios_are_refused():
    with pytest.raises(ScenarioError, match="kind: 'open_loop'"):
        run_scenario(load_scenario("openloop_0_5Hz"))


def test_outer_followers_keep_the_inner_gimbals_off_their_stops():
    scenario = dataclasses.replace(load_scenario("turbulence_1_6Hz"), duration_s=7.0)
    result = run_scenario(scenario)
    for axis in ("inner_az", "inner_el"):
        assert np.max(np.abs(result.joint_angles[axis])) < 3.0 * DEG
    # the turntable swings 3 deg; the outer gimbals take it
    assert np.max(np.abs(result.joint_angles["outer_az"])) > 2.0 * DEG


def test_campaign_command_writes_the_table5_statistics_as_json(tmp_path, capsys):
    import json

    from isp_twin.cli import main

    out = tmp_path / "c.json"
    assert main(["campaign", "tracking_0_5Hz", "-n", "2", "--jobs", "1", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["scenario"] == "tracking_0_5Hz" and doc["seeds"] == [1, 2]
    stats = doc["metrics"]["inner_az"]
    # Each run is the scenario run alone with that seed and that controller.
    scenario = load_scenario("tracking_0_5Hz")
    for variant, nfc in (("PI", False), ("PI+NFC", True)):
        alone = [
            run_scenario(scenario.with_nfc(nfc), seed=seed).metrics["inner_az"] for seed in (1, 2)
        ]
        js = [m["isolation_percent"] for m in alone]
        assert stats[variant]["runs"] == js
        assert stats[variant]["average"] == pytest.approx(np.mean(js))
        assert stats[variant]["rms_error_deg_s"] == [m["rms_error_deg_s"] for m in alone]
    assert "NFC reduces the average J" in capsys.readouterr().out


def test_campaign_command_rejects_an_open_loop_scenario_and_an_axis_without_j(capsys):
    from isp_twin.cli import main

    assert main(["campaign", "openloop_0_5Hz", "-n", "1"]) == 2
    assert "closed_loop" in capsys.readouterr().err
    assert main(["campaign", "tracking_0_5Hz", "-n", "1", "--axis", "inner_el"]) == 2
    assert "inner_el sees no carrier motion" in capsys.readouterr().err


def test_the_run_records_exactly_the_signal_table_and_the_recorder_styles_each(short_run):
    from isp_twin.experiments.signals import CLOSED_LOOP_SIGNALS, INNER_SIGNALS, OUTER_SIGNALS
    from isp_twin.output.entities import SIGNAL_STYLES

    assert tuple(short_run.signals) == CLOSED_LOOP_SIGNALS.signals
    assert tuple(short_run.joint_angles) == CLOSED_LOOP_SIGNALS.joints
    for sig in INNER_SIGNALS + OUTER_SIGNALS:
        assert sig.name in SIGNAL_STYLES
    # the block of an axis holds its signals in table order
    cols = CLOSED_LOOP_SIGNALS.signals[CLOSED_LOOP_SIGNALS.block("outer_el")]
    assert cols == ("outer_el/follow_error", "outer_el/command")


def test_stepping_a_closed_loop_by_hand_gives_the_same_run_and_reset_repeats_it():
    from isp_twin.experiments.closed_loop import ClosedLoop

    scenario = parse_scenario({**SHORT, "duration_s": 2.1}, "short.yaml")
    loop = ClosedLoop(scenario, seed=7)
    while loop.done < loop.n:
        loop.step()
    stepped = loop.result()
    loop.reset()
    assert loop.done == 0
    loop.run()
    again = loop.result()
    whole = run_scenario(scenario, seed=7)
    assert stepped.metrics == whole.metrics == again.metrics
    for key in whole.signals:
        assert np.array_equal(stepped.signals[key], whole.signals[key])
        assert np.array_equal(again.signals[key], whole.signals[key])
    with pytest.raises(SimulationDiverged, match="ends at sample"):
        loop.step()


def test_the_twins_fast_sense_reads_the_same_numbers_as_its_state():
    from isp_twin.experiments.closed_loop import ClosedLoop

    loop = ClosedLoop(parse_scenario({**SHORT, "duration_s": 2.1}, "short.yaml"))
    for _ in range(700):  # moving, with the turntable swinging
        loop.step()
    st = loop.twin.state()
    angle, rate, gyro, carrier, friction, regime, table = loop.twin.sense()
    assert angle == st.angle.tolist() and rate == st.rate.tolist()
    assert gyro == st.gyro.tolist() and carrier == st.carrier_rate.tolist()
    assert friction == st.friction.tolist() and regime == st.regime.tolist()
    assert table == st.table_angle.tolist()
