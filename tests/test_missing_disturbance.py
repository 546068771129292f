"""The missing-disturbance findings of docs/calibration.md, as properties that could fail.

* The carrier's angular motion reaches a gimbal through its inertia products
  (MuJoCo computes the coupling from the body's inertia), but for the paper's
  turbulence it is far below the gimbal's friction torque: not the missing
  disturbance.
* A torque ripple of the outer gimbals' motors (periodic in their angle, so
  its frequency follows the carrier's rate) reaches the inner gimbal's error
  as RMS, while the peak stays the reversal burst.
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest

from isp_twin.experiments.closed_loop import ClosedLoop
from isp_twin.experiments.scenario import load_scenario
from isp_twin.model.parameters import EffectSpec
from isp_twin.model.twin import Twin
from isp_twin.resources import model_path
from isp_twin.units import DEG


def _dof(model, name):
    return int(model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)])


def _full_inertia(model) -> np.ndarray:
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    m = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m)
    return m


def test_an_inertia_product_couples_the_carrier_roll_into_the_azimuth_as_the_rigid_body_says():
    theta = math.radians(20.0)
    text = model_path().read_text()
    old = '<inertial pos="0 0 0" mass="8" diaginertia="0.0256 0.05447 0.05447"/>'
    assert old in text
    tilted = old.replace(
        'pos="0 0 0"', f'pos="0 0 0" quat="{math.cos(theta / 2)} 0 {math.sin(theta / 2)} 0"'
    )
    shipped = mujoco.MjModel.from_xml_string(text)
    model = mujoco.MjModel.from_xml_string(text.replace(old, tilted))
    az, roll = _dof(model, "inner_az"), _dof(model, "table_roll")
    # principal axes turned by theta about y: I_zx = sin(theta) cos(theta) (Izz - Ixx)
    expected = math.sin(theta) * math.cos(theta) * (0.05447 - 0.0256)
    assert _full_inertia(model)[az, roll] == pytest.approx(expected, rel=1e-6)
    assert _full_inertia(shipped)[az, roll] == pytest.approx(0.0, abs=1e-12)


def test_inertial_coupling_under_the_paper_turbulence_is_below_one_percent_of_friction(
    paper_params,
):
    twin = Twin(paper_params)
    scenario = load_scenario("turbulence_1_6Hz")
    motions = scenario.turntable.motions()
    # carrier rate and angular acceleration, all three table axes at their peaks
    w = math.sqrt(sum(m.rate_amplitude**2 for m in motions.values()))
    alpha = math.sqrt(
        sum((m.rate_amplitude * 2 * math.pi * m.freq_hz) ** 2 for m in motions.values())
    )
    body = mujoco.mj_name2id(twin.model, mujoco.mjtObj.mjOBJ_BODY, "inner_az")
    principal = twin.model.body_inertia[body]
    spread = float(principal.max() - principal.min())
    # any orientation of the principal axes: |I_zx| <= spread / 2; gyroscopic
    # (I_yy - I_xx) w_x w_y <= spread * w^2
    bound = spread / 2 * alpha + spread * w**2
    assert bound < 0.01 * float(twin.axes["inner_az"].coulomb.min())


def _outer_ripple(params, amplitude_rad_s2: float):
    spec = EffectSpec(
        "cogging",
        {"amplitude_rad_s2": amplitude_rad_s2, "period_rad": 2.0 * DEG, "phase_rad": 0.0},
    )
    for name in ("outer_az", "outer_el"):
        params = params.with_axis(name, dataclasses.replace(params.axis(name), effects=(spec,)))
    return params


def test_outer_motor_ripple_raises_the_inner_rms_error_and_leaves_its_peak(paper_params):
    scenario = load_scenario("table4_1_6Hz_pi")
    for seed in (1, 2):
        out = {}
        for amplitude in (0.0, 5.0):
            loop = ClosedLoop(scenario, params=_outer_ripple(paper_params, amplitude), seed=seed)
            loop.run()
            out[amplitude] = loop.result().metrics["inner_az"]
        rms = out[5.0]["rms_error_deg_s"] / out[0.0]["rms_error_deg_s"]
        peak = out[5.0]["max_abs_error_deg_s"] / out[0.0]["max_abs_error_deg_s"]
        assert rms > 1.5, f"seed {seed}: rms x{rms:.2f}"
        assert 0.8 < peak < 1.25, f"seed {seed}: peak x{peak:.2f}"
