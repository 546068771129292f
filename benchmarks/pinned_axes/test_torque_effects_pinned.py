"""Torque effects end to end on the benchmark axes that shaped the alike
restart, the read-out round and the second refit at the other gyro read-out
(`tests/test_torque_effects_reference.py` runs the first axis of each)."""

from __future__ import annotations

import pytest
from test_torque_effects_reference import (
    alike_pair_answered,
    cogging_found,
    judged_at_the_other_read_out,
)


# Unbalance seed 3 answered the spring at stop 20 (the alike restart,
# `rounds._alike_stage`); cable spring seed 7 was left tentative at the
# base's read-out and shaped the read-out round (`search._tentative_read_out`):
# regression tests, not their validation (docs/diagnosis.md "Stop 21").
@pytest.mark.parametrize(("effect", "seed"), [("unbalance", 3), ("cable_spring", 7)])
def test_the_alike_pair_answers_the_effect_in_the_data(tmp_path, effect, seed):
    alike_pair_answered(tmp_path, effect, seed)


def test_a_tentative_spring_is_refitted_from_the_rates_identified_at_the_other_read_out(
    tmp_path,
):
    """Cable spring seed 22, a 14 ms axis (docs/diagnosis.md "Stop 27"),
    shaped the second refit and the lower `FLIP_GAIN`: the spring refitted
    from the point-sampled rates at the averaged read-out fitted no better,
    where the rates `identify` finds there with the spring held take the
    stiffness from 3 % short to the truth's and the training cost 2.9 %
    lower."""
    judged_at_the_other_read_out(
        tmp_path, "cable_spring", 22, ("cable_spring",), "stiffness_1_s2", 0.01
    )


def test_a_tentative_cogging_is_judged_at_the_half_plane_identify_chooses_with_it(tmp_path):
    """Reference cogging seed 464 (covered design), a ripple stronger than
    the Coulomb levels: the base, at 500 noise floors, chose the half-plane
    read 0.75 step late, and there the cogging, found to 0.01 %, stopped at
    1.83 noise floors on the training runs and was set aside (`none`).
    `identify` with it held chooses no shift, and the tentative effect is
    now judged there too, not only at another gyro reading
    (`search._tentative_read_out`). A regression test, not its validation
    (docs/diagnosis.md "Stop 81")."""
    cogging_found(tmp_path, 464)
