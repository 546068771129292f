"""The shared names (isp_twin.vocabulary) agree with the model, the paper and their users."""

from __future__ import annotations

import typing

import mujoco
import numpy as np
import pytest

from isp_twin.errors import ParameterError
from isp_twin.experiments.scenario import OpenLoop
from isp_twin.model.axis_model import simulate
from isp_twin.model.parameters import load_parameters
from isp_twin.model.substep_model import simulate_substeps
from isp_twin.output.kinematics import JOINTS
from isp_twin.resources import default_parameters_path, model_path
from isp_twin.vocabulary import (
    GIMBAL_AXES,
    INNER_AXES,
    JOINT_CHAIN,
    OUTER_AXES,
    REGIMES,
    SIDE_L,
    SIDE_R,
    SIDES,
    TABLE_JOINTS,
    check_side,
)


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_path(str(model_path()))


def test_the_regimes_are_the_papers_parameter_vector_order():
    # Eq. 8: X = [R+ ..., R- ..., L+ ..., L- ...]; index = 2 * side + direction.
    assert REGIMES == ("R+", "R-", "L+", "L-")
    assert [REGIMES[2 * s + d][0] for s in (SIDE_R, SIDE_L) for d in (0, 1)] == [
        SIDES[SIDE_R],
        SIDES[SIDE_R],
        SIDES[SIDE_L],
        SIDES[SIDE_L],
    ]


def test_the_joint_chain_is_the_models_body_nesting(model):
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in JOINT_CHAIN]
    assert min(ids) >= 0
    bodies = [int(model.jnt_bodyid[j]) for j in ids]
    # each joint's body is a child of the previous joint's body
    assert all(int(model.body_parentid[b]) == a for a, b in zip(bodies, bodies[1:]))
    assert sorted(JOINT_CHAIN) == sorted(TABLE_JOINTS + GIMBAL_AXES)
    assert GIMBAL_AXES == INNER_AXES + OUTER_AXES


def test_the_recorded_joint_axes_are_the_models(model):
    unit = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
    assert [name for name, _ in JOINTS] == list(JOINT_CHAIN)
    for name, axis in JOINTS:
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        np.testing.assert_allclose(np.abs(model.jnt_axis[j]), unit[axis])


def test_the_open_loop_scenario_offers_every_gimbal():
    hint = typing.get_type_hints(OpenLoop)["axis"]
    assert typing.get_args(hint) == GIMBAL_AXES


@pytest.mark.parametrize("side", [None, SIDE_R, SIDE_L])
def test_a_side_is_none_or_an_index(side):
    assert check_side(side) is side


@pytest.mark.parametrize("side", [1.0, -1.0, -1, 2, True, "R"])
def test_any_other_side_is_refused(side):
    with pytest.raises(ParameterError, match="SIDE_R"):
        check_side(side)


@pytest.mark.parametrize("engine", [simulate, simulate_substeps])
def test_the_models_refuse_the_old_float_side(engine):
    # +1.0 meant R before the side became an index; read as an index it would be L.
    rate = load_parameters(default_parameters_path()).axis("inner_az").rate_params()
    with pytest.raises(ParameterError, match="side 1.0"):
        engine(rate, np.zeros(10), 1e-3, side=1.0)
