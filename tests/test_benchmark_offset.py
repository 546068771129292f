"""The reference benchmark's second scoring of a torque offset
(`benchmarks/identify_reference.py`, `offset_equivalence`): an equivalent
``none`` is right when the offset each angle side's levels imply is the
truth's on that side, whether or not the two sides agree."""

from __future__ import annotations

import math

import pytest
from reference_benchmark import reference_benchmark

DT = 1e-3
POLE = 0.99
T0 = -2.0  # the torque offset [rad/s^2]
#: Coulomb and static levels per regime [rad/s^2]; the bearings' asymmetry
#: differs on the two sides: R (-0.3) and L (+0.2).
COULOMB = {"R+": 5.0, "R-": 4.4, "L+": 5.0, "L-": 5.4}
STATIC = {r: 2.0 * c for r, c in COULOMB.items()}
#: The offset each side's levels imply: T0 + (Tc- - Tc+)/2.
SIDES = (T0 - 0.3, T0 + 0.2)


def _truth(static=STATIC) -> dict:
    """A reference truth in rate form (b·T per sample, exact hold of the pole)."""
    per_accel = -math.log(POLE) / ((1.0 - POLE) * DT)
    regimes = {
        r: {"pole": POLE, "coulomb": COULOMB[r] / per_accel, "static": static[r] / per_accel}
        for r in COULOMB
    }
    return {
        "sample_time_s": DT,
        "effects": [{"name": "torque_offset", "params": {"accel_rad_s2": T0}}],
        "rate_form": {"regimes": regimes},
    }


def _diag(right: float, left: float, answer: str = "none") -> dict:
    return {
        "selected_effect": answer,
        "equivalent_torque_offset": {
            "accel_rad_s2": 0.5 * (right + left),
            "right_side_rad_s2": right,
            "left_side_rad_s2": left,
            "consistent": False,
        },
    }


def _scored(truth, diag, after=1.0) -> dict:
    return reference_benchmark().offset_equivalence(truth, diag, after)


def test_the_truths_sides_are_stated_exactly_and_the_answer_is_right():
    """The two sides differ by the bearings' asymmetry (far beyond any
    interval): an answer that states each side's offset is right."""
    out = _scored(_truth(), _diag(*SIDES))
    assert out["offset_equivalent_axis"]
    assert out["offset_sides_true"] == pytest.approx(SIDES)
    assert out["offset_right_equivalent"]


@pytest.mark.parametrize("side", [0, 1])
def test_one_side_off_by_more_than_a_tenth_of_the_offset_is_wrong(side):
    stated = list(SIDES)
    stated[side] += 0.15 * abs(T0)
    assert not _scored(_truth(), _diag(*stated))["offset_right_equivalent"]


def test_above_the_bound_held_out_is_wrong():
    assert not _scored(_truth(), _diag(*SIDES), after=1.6)["offset_right_equivalent"]


def test_where_a_shifted_level_goes_negative_the_axis_is_not_equivalent():
    """R- static 1.5 rad/s^2 shifted by T0 = -2: -0.5, below zero."""
    out = _scored(_truth({**STATIC, "R-": 1.5}), _diag(*SIDES))
    assert not out["offset_equivalent_axis"]
    assert not out["offset_right_equivalent"]


def test_another_answer_is_not_scored_equivalent():
    assert not _scored(_truth(), _diag(*SIDES, answer="cable_spring")).get(
        "offset_right_equivalent"
    )
