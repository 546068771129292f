"""The MJCF model: compiles, is fully named, steps cleanly, and the turntable tracks."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

from isp_twin.model.parameters import load_parameters
from isp_twin.model.twin import GIMBALS, TABLE_JOINTS, Twin
from isp_twin.resources import default_parameters_path, model_path
from isp_twin.units import DEG


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(model_path()))


def assert_no_warnings(data: mujoco.MjData) -> None:
    counts = {
        mujoco.mjtWarning(i).name: data.warning[i].number
        for i in range(mujoco.mjtWarning.mjNWARNING)
    }
    assert not any(counts.values()), f"MuJoCo warnings: {counts}"


def names(model: mujoco.MjModel, obj: mujoco.mjtObj, count: int) -> list[str]:
    return [mujoco.mj_id2name(model, obj, i) for i in range(count)]


def test_element_order_follows_menagerie():
    root = ET.parse(model_path()).getroot()
    order = [child.tag for child in root]
    expected = ["compiler", "option", "default", "worldbody", "actuator", "sensor", "keyframe"]
    assert order == expected


def test_every_joint_actuator_sensor_body_and_site_is_named(model):
    for obj, count in (
        (mujoco.mjtObj.mjOBJ_JOINT, model.njnt),
        (mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu),
        (mujoco.mjtObj.mjOBJ_SENSOR, model.nsensor),
        (mujoco.mjtObj.mjOBJ_BODY, model.nbody),
        (mujoco.mjtObj.mjOBJ_SITE, model.nsite),
        (mujoco.mjtObj.mjOBJ_GEOM, model.ngeom),
    ):
        assert all(names(model, obj, count)), f"unnamed {obj.name}"


def test_joints_actuators_and_sensors_carry_the_hardware_names(model):
    assert names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt) == list(
        TABLE_JOINTS + ("outer_az", "outer_el", "inner_el", "inner_az")
    )
    actuators = set(names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu))
    assert actuators == set(TABLE_JOINTS) | {f"motor_{g}" for g in GIMBALS}
    sensors = set(names(model, mujoco.mjtObj.mjOBJ_SENSOR, model.nsensor))
    assert {"gyro_inner_az", "gyro_inner_el", "gyro_table"} <= sensors
    assert {f"resolver_{g}" for g in GIMBALS} <= sensors


def test_inner_gimbals_are_limited_to_plus_minus_4_degrees(model):
    for name in ("inner_az", "inner_el"):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        assert model.jnt_limited[jid]
        np.testing.assert_allclose(model.jnt_range[jid], [-4 * DEG, 4 * DEG], rtol=1e-7)
    assert all(model.jnt_limited), "every joint is limited"


def test_the_xml_holds_no_friction_or_damping(model):
    # friction comes from the parameter set, written by the twin each step
    assert not model.dof_damping.any()
    assert not model.dof_frictionloss.any()
    assert not model.dof_armature.any()


def test_balanced_gimbals_feel_no_gravity_torque(model):
    data = mujoco.MjData(model)
    data.qpos[:] = [0.1, -0.2, 0.15, 0.5, -0.3, 0.05, -0.05]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qfrc_bias, 0.0, atol=1e-9)


def test_model_steps_one_second_with_turntable_motion_without_warnings(model):
    data = mujoco.MjData(model)
    n = int(round(1.0 / model.opt.timestep))
    for k in range(n):
        t = k * model.opt.timestep
        data.ctrl[:3] = 3 * DEG * np.sin(2 * np.pi * t / 6.0)
        data.ctrl[3:] = 0.5 * np.sin(2 * np.pi * 0.5 * t)
        mujoco.mj_step(model, data)
    assert_no_warnings(data)
    assert np.all(np.isfinite(data.qvel))
    assert data.time == pytest.approx(1.0)


def test_turntable_tracks_the_3_degree_one_sixth_hz_sine_despite_the_gimbals():
    """Paper Sect. 4.2: 3 deg, 1/6 Hz on all three axes, rate amplitude pi deg/s."""
    twin = Twin(load_parameters(default_parameters_path()))
    f, amplitude = 1.0 / 6.0, 3 * DEG
    n = 6000
    t = (np.arange(n) + 1) * twin.dt
    target = amplitude * np.sin(2 * np.pi * f * t)
    rate = np.empty((n, 3))
    angle = np.empty((n, 3))
    for k in range(n):
        # the inner azimuth slides (Eq. 4 shape): its reaction reaches the table
        twin.step([950 * np.cos(np.pi * t[k]), 0.0, 0.0, 0.0], np.full(3, target[k]))
        s = twin.state()
        rate[k], angle[k] = s.table_rate, s.table_angle
    assert_no_warnings(twin.data)
    steady = t > 1.0  # after the start-up transient (target rate jumps to pi deg/s)
    rate_ref = amplitude * 2 * np.pi * f * np.cos(2 * np.pi * f * t)
    rate_err = np.abs(rate - rate_ref[:, None])[steady].max() / (amplitude * 2 * np.pi * f)
    angle_err = np.abs(angle - target[:, None])[steady].max() / amplitude
    # 30 Hz servo: lag 2*zeta*f/f_n = 0.8 % (models/README.md)
    assert rate_err < 0.02, f"rate tracking error {100 * rate_err:.2f} % of pi deg/s"
    assert angle_err < 0.02, f"angle tracking error {100 * angle_err:.2f} % of 3 deg"
