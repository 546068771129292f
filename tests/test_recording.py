"""Rerun recordings: files verify, hold the run in display units, survive Ctrl-C."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from isp_twin.errors import DataError, ResourceNotFound
from isp_twin.experiments.results import RunResult
from isp_twin.output import readback, recording, rerun_writer
from isp_twin.output.kinematics import JOINTS, joint_quaternions, line_of_sight
from isp_twin.output.readback import read_series, read_text, read_views, verify_recording
from isp_twin.output.recording import record_residuals, record_run
from isp_twin.units import DEG

DT = 1e-3  # 1 kHz, the runner's rate
INNER_SIGNALS = (
    "omega_carrier",
    "omega_inertial",
    "omega_relative",
    "gyro",
    "command",
    "friction",
    "nfc",
    "regime",
)


def synthetic_run(duration_s: float = 3.0, *, interrupted: bool = False) -> RunResult:
    """A closed-loop-like run made of analytic sines (1.6 Hz turbulence)."""
    t = np.arange(round(duration_s / DT)) * DT
    carrier = 2.0 * DEG * np.sin(2 * np.pi * 1.6 * t)
    signals: dict[str, np.ndarray] = {}
    for k, axis in enumerate(("inner_az", "inner_el")):
        signals[f"{axis}/omega_carrier"] = carrier
        signals[f"{axis}/omega_inertial"] = 0.01 * carrier
        signals[f"{axis}/omega_relative"] = -0.99 * carrier
        signals[f"{axis}/gyro"] = 0.01 * carrier
        signals[f"{axis}/command"] = 300.0 * np.sin(2 * np.pi * 1.6 * t + k)
        signals[f"{axis}/friction"] = 0.05 * np.sign(np.cos(2 * np.pi * 1.6 * t))
        signals[f"{axis}/nfc"] = 40.0 * np.sign(np.cos(2 * np.pi * 1.6 * t))
        signals[f"{axis}/regime"] = (np.floor(t * 4) % 4).astype(float)
    for axis in ("outer_az", "outer_el"):
        signals[f"{axis}/follow_error"] = 0.1 * DEG * np.sin(2 * np.pi * 0.5 * t)
    joints = {name: 0.2 * np.sin(2 * np.pi * 0.3 * t + i) for i, (name, _) in enumerate(JOINTS)}
    return RunResult(
        scenario="synthetic",
        scenario_text="duration_s: 3\nturbulence:\n  freq_hz: 1.6\n",
        parameters_file="models/params/paper_table2.yaml",
        parameters_text="inner_az:\n  R+: {a: 0.99}\n",
        seed=7,
        t=t,
        signals=signals,
        joint_angles=joints,
        metrics={"J_db": {"inner_az": -21.5, "inner_el": -19.0}, "passed": True},
        interrupted=interrupted,
        rig="paper_rig",
        rig_text="name: paper_rig\nknobs:\n  gyro_scale: {value: 70.0}\n",
        nfc_parameters="models/params/twin_identified.yaml",
    )


@pytest.fixture(scope="module")
def run() -> RunResult:
    return synthetic_run()


@pytest.fixture(scope="module")
def recorded(run, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "synthetic.rrd"
    return record_run(run, path, decimate_3d=20)


def leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.iterdir() if p.name.endswith(".part")]


# --- the file -------------------------------------------------------------


def test_recorded_run_passes_rerun_verify(recorded):
    verify_recording(recorded)
    assert not leftovers(recorded.parent)


def test_verify_rejects_a_truncated_recording(recorded, tmp_path):
    broken = tmp_path / "broken.rrd"
    broken.write_bytes(recorded.read_bytes()[: recorded.stat().st_size // 2])
    with pytest.raises(DataError, match="broken.rrd"):
        verify_recording(broken)


def test_rates_are_shown_in_deg_s_on_the_run_time_base(run, recorded):
    t, omega1 = read_series(recorded, "/inner_az/rates/omega_inertial_deg_s")
    np.testing.assert_allclose(t, run.t, atol=1e-9)
    np.testing.assert_allclose(omega1, np.asarray(run.signals["inner_az/omega_inertial"]) / DEG)
    _, omega = read_series(recorded, "/inner_el/rates/omega_carrier_deg_s")
    assert np.max(np.abs(omega)) == pytest.approx(2.0, rel=1e-3)  # 2 deg/s amplitude


def test_digits_torque_and_regime_are_recorded_unscaled(run, recorded):
    for entity, name in (
        ("/inner_az/drive/command_digits", "inner_az/command"),
        ("/inner_az/drive/nfc_digits", "inner_az/nfc"),
        ("/inner_el/friction/friction_N_m", "inner_el/friction"),
        ("/inner_el/regime/regime_index", "inner_el/regime"),
    ):
        _, values = read_series(recorded, entity)
        np.testing.assert_array_equal(values, run.signals[name])


def test_outer_follow_error_is_shown_in_deg(run, recorded):
    _, err = read_series(recorded, "/outer_el/follow/follow_error_deg")
    np.testing.assert_allclose(err, np.asarray(run.signals["outer_el/follow_error"]) / DEG)


def test_metadata_holds_scenario_parameters_and_metrics(run, recorded):
    assert run.scenario_text in read_text(recorded, "/metadata/scenario")
    params = read_text(recorded, "/metadata/parameters")
    assert run.parameters_text in params and run.parameters_file in params
    metrics_doc = read_text(recorded, "/metadata/metrics")
    json_block = metrics_doc.split("```json\n")[1].split("\n```")[0]
    assert json.loads(json_block) == run.metrics
    run_doc = read_text(recorded, "/metadata/run")
    assert "| seed | 7 |" in run_doc and "| interrupted | False |" in run_doc
    assert "| rig | paper_rig |" in run_doc
    assert "| nfc_parameters | models/params/twin_identified.yaml |" in run_doc
    assert run.rig_text in read_text(recorded, "/metadata/rig")


def test_3d_joints_are_decimated_and_follow_the_angles(run, recorded):
    t, quat = read_series(recorded, "/scene/table_yaw/table_pitch", "Transform3D:quaternion")
    np.testing.assert_allclose(t, run.t[::20], atol=1e-9)
    angle = np.asarray(run.joint_angles["table_pitch"])[::20]
    np.testing.assert_allclose(quat, joint_quaternions(angle, "y"), atol=1e-6)
    _, los = read_series(recorded, "/scene/line_of_sight", "Arrows3D:vectors")
    np.testing.assert_allclose(
        los / np.linalg.norm(los, axis=1, keepdims=True),
        line_of_sight({k: np.asarray(v)[::20] for k, v in run.joint_angles.items()}, len(t)),
        atol=1e-6,
    )


def test_layout_has_3d_per_axis_series_follow_error_and_metadata_views(recorded):
    origins = {(origin, kind) for _, origin, kind in read_views(recorded)}
    expected = {("/scene", "3D")}
    for axis in ("inner_az", "inner_el"):
        for group in ("rates", "drive", "friction", "regime"):
            expected.add((f"/{axis}/{group}", "TimeSeries"))
    for doc in ("run", "scenario", "parameters", "metrics"):
        expected.add((f"/metadata/{doc}", "TextDocument"))
    assert expected <= origins
    names = [name for name, _, _ in read_views(recorded)]
    assert "outer follow error [deg]" in names


# --- kinematics -----------------------------------------------------------


def rotate_by_quaternion(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The slow, obvious way: v' = q v q*, quaternions (x, y, z, w)."""
    x, y, z, w = q
    vx, vy, vz = v
    # q * (v, 0)
    a = np.array(
        [
            w * vx + y * vz - z * vy,
            w * vy + z * vx - x * vz,
            w * vz + x * vy - y * vx,
            -x * vx - y * vy - z * vz,
        ]
    )
    # (q v) * q*, q* = (-x, -y, -z, w)
    ax, ay, az, aw = a
    return np.array(
        [
            aw * -x + ax * w + ay * -z - az * -y,
            aw * -y + ay * w + az * -x - ax * -z,
            aw * -z + az * w + ax * -y - ay * -x,
        ]
    )


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_joint_quaternion_rotates_like_the_line_of_sight_kinematics(axis):
    angles = np.linspace(-3.0, 3.0, 13)
    quats = joint_quaternions(angles, axis)
    np.testing.assert_allclose(np.linalg.norm(quats, axis=1), 1.0)
    # A single joint turned, all others at zero.
    joint = next(name for name, a in JOINTS if a == axis)
    los = line_of_sight({joint: angles}, len(angles))
    slow = np.array([rotate_by_quaternion(q, np.array([1.0, 0.0, 0.0])) for q in quats])
    np.testing.assert_allclose(los, slow, atol=1e-12)


def test_line_of_sight_is_fixed_when_outer_az_cancels_table_yaw():
    theta = np.linspace(-1.0, 1.0, 21)
    los = line_of_sight({"table_yaw": theta, "outer_az": -theta}, len(theta))
    np.testing.assert_allclose(los, np.tile([1.0, 0.0, 0.0], (len(theta), 1)), atol=1e-12)


def test_line_of_sight_tilts_down_for_positive_elevation_about_y():
    los = line_of_sight({"outer_el": np.array([np.pi / 2])}, 1)
    np.testing.assert_allclose(los[0], [0.0, 0.0, -1.0], atol=1e-12)


# --- partial and interrupted runs ------------------------------------------


def test_open_loop_run_with_few_signals_and_no_joints_records(tmp_path):
    t = np.arange(500) * DT
    result = RunResult(
        scenario="open_loop",
        scenario_text="mode: open_loop\n",
        parameters_file="p.yaml",
        parameters_text="",
        seed=0,
        t=t,
        signals={"inner_az/gyro": np.sin(t), "inner_az/command": 100 * np.ones_like(t), "probe": t},
    )
    path = record_run(result, tmp_path / "open_loop.rrd")
    verify_recording(path)
    _, probe = read_series(path, "/other/other/probe_si")
    np.testing.assert_array_equal(probe, t)


def test_interrupted_run_records_what_it_has(tmp_path):
    full = synthetic_run(1.0, interrupted=True)
    n = 377  # stopped part-way through
    result = RunResult(
        **{
            **full.__dict__,
            "t": full.t[:n],
            "signals": {k: v[:n] for k, v in full.signals.items()},
            "joint_angles": {k: v[:n] for k, v in full.joint_angles.items()},
        }
    )
    path = record_run(result, tmp_path / "stopped.rrd")
    verify_recording(path)
    assert "(interrupted)" in read_text(path, "/metadata/run")
    t, _ = read_series(path, "/inner_az/rates/gyro_deg_s")
    assert len(t) == n


def test_run_stopped_before_the_first_sample_still_verifies(tmp_path):
    empty = RunResult(
        "empty",
        "",
        "p.yaml",
        "",
        0,
        np.zeros(0),
        {"inner_az/gyro": np.zeros(0)},
        {"table_yaw": np.zeros(0)},
        interrupted=True,
    )
    verify_recording(record_run(empty, tmp_path / "empty.rrd"))


def _interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def test_ctrl_c_while_recording_leaves_no_file_and_no_part(run, tmp_path, monkeypatch):
    monkeypatch.setattr(recording, "_log_signals", _interrupt)
    target = tmp_path / "new.rrd"
    with pytest.raises(KeyboardInterrupt):
        record_run(run, target)
    assert not target.exists()
    assert not leftovers(tmp_path)


def test_ctrl_c_while_recording_keeps_the_previous_complete_file(run, tmp_path, monkeypatch):
    target = record_run(run, tmp_path / "kept.rrd")
    before = target.read_bytes()
    monkeypatch.setattr(recording, "_log_scene", _interrupt)
    with pytest.raises(KeyboardInterrupt):
        record_run(run, target)
    assert target.read_bytes() == before
    assert not leftovers(tmp_path)
    verify_recording(target)


def test_real_ctrl_c_while_recording_finishes_the_file_then_interrupts(
    run, tmp_path, monkeypatch, ctrl_c_delivered
):
    log_signals = recording._log_signals

    def ctrl_c_then_log(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)
        log_signals(*args, **kwargs)

    monkeypatch.setattr(recording, "_log_signals", ctrl_c_then_log)
    target = tmp_path / "finished.rrd"
    with pytest.raises(KeyboardInterrupt):
        record_run(run, target)
    verify_recording(target)
    assert not leftovers(tmp_path)
    _, gyro = read_series(target, "/inner_az/rates/gyro_deg_s")
    assert len(gyro) == len(run.t)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_signal_of_wrong_length_is_refused_before_writing(run, tmp_path):
    bad = RunResult(**{**run.__dict__, "signals": {**run.signals, "inner_az/nfc": np.zeros(5)}})
    with pytest.raises(DataError, match="inner_az/nfc"):
        record_run(bad, tmp_path / "bad.rrd")
    assert list(tmp_path.iterdir()) == []


# --- residuals --------------------------------------------------------------


def test_residual_recording_verifies_and_holds_both_residuals(tmp_path):
    t = np.arange(2000) * DT
    angle = 10 * DEG * np.sin(2 * np.pi * 0.5 * t)
    rate = np.gradient(angle, t)
    before = 0.2 * DEG * np.sin(6 * angle)  # a position-periodic torque left unmodelled
    after = 0.1 * before
    path = record_residuals(
        "inner_az",
        t,
        before,
        after,
        tmp_path / "res.rrd",
        angle=angle,
        rate=rate,
        metadata={"effect": "cogging", "params": {"periods": 6}},
    )
    verify_recording(path)
    _, got_before = read_series(path, "/residuals/time/before_deg_s")
    np.testing.assert_allclose(got_before, before / DEG)
    doc = read_text(path, "/metadata/residuals")
    rms_before = np.sqrt(np.mean((before / DEG) ** 2))
    assert f"| rms_before_deg_s | {rms_before:.6g} |" in doc
    assert "| params/periods | 6 |" in doc


def test_residual_without_angle_or_rate_verifies(tmp_path):
    t = np.arange(100) * DT
    verify_recording(record_residuals("x", t, np.sin(t), 0 * t, tmp_path / "r.rrd"))


# --- live viewer ------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_connect_streams_to_a_viewer_proxy_and_still_saves(run, tmp_path):
    port = _free_port()
    proxy = subprocess.Popen(
        [readback.rerun_executable(), "--serve-grpc", "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        # The `rerun` script starts the real binary as a child: own group, killed whole.
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 15.0
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "rerun proxy did not start"
                time.sleep(0.1)
        path = record_run(
            run, tmp_path / "live.rrd", connect=f"rerun+http://127.0.0.1:{port}/proxy"
        )
        verify_recording(path)
    finally:
        os.killpg(proxy.pid, signal.SIGKILL)
        proxy.wait()


def test_missing_recording_is_reported_by_name(tmp_path):
    with pytest.raises(ResourceNotFound, match="nope.rrd"):
        verify_recording(tmp_path / "nope.rrd")


def test_unreachable_viewer_is_reported_and_the_file_is_still_saved(run, tmp_path, monkeypatch):
    monkeypatch.setattr(rerun_writer, "_VIEWER_TIMEOUT_S", 0.5)
    url = f"rerun+http://127.0.0.1:{_free_port()}/proxy"  # nothing listens there
    target = tmp_path / "offline.rrd"
    with pytest.raises(ResourceNotFound, match="offline.rrd"):
        record_run(run, target, connect=url)
    verify_recording(target)


def test_residual_of_wrong_length_is_refused_naming_the_array(tmp_path):
    t = np.arange(100) * DT
    with pytest.raises(DataError, match="residuals 'inner_el': array 'angle'"):
        record_residuals("inner_el", t, t, t, tmp_path / "r.rrd", angle=np.zeros(99))
    assert list(tmp_path.iterdir()) == []


def test_the_isolation_error_has_its_own_view_titled_with_j(run, tmp_path):
    from dataclasses import replace

    metrics = {
        "inner_az": {"isolation_percent": 13.714, "max_abs_error_deg_s": 0.4},
        "inner_el": {"isolation_percent": 11.652, "max_abs_error_deg_s": 0.3},
    }
    path = record_run(replace(run, metrics=metrics, view_start_s=1.0), tmp_path / "j.rrd")
    views = read_views(path)
    for axis, j in (("inner_az", "13.71"), ("inner_el", "11.65")):
        title = f"{axis}: isolation error ω1 [deg/s], J = {j} %"
        assert (title, f"/{axis}/rates/omega_inertial_deg_s", "TimeSeries") in views
    # Without J in the metrics (an open-loop run) there is no such view.
    assert not any(
        "isolation error" in name for name, _, _ in read_views(record_run(run, tmp_path / "n.rrd"))
    )
