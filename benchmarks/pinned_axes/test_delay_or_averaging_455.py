"""A sub-sample input delay read as the gyro's averaging
(`search._delay_or_averaging`), end to end on the axis that shaped it
(`tests/test_delay_or_averaging.py` checks the decision with stand-ins)."""

from __future__ import annotations

from identified_runs import reference_identified_then_diagnosed

from isp_twin.estimation.verdict import CONVERGED_RATIO


def test_reference_clean_455_answers_none_at_the_averaged_reading(tmp_path):
    """Reference clean seed 455 (covered design; the reference gyro averages,
    no delay), a pin, not a validation: `identify` with defaults keeps the
    point reading, and until stop 79 `diagnose` answered a 0.25 ms
    `input_delay` at 1.21 noise floors held out."""
    exp, d = reference_identified_then_diagnosed(
        tmp_path, 455, None, ("input_delay",), held_out="covered"
    )
    assert exp.truth()["effects"] == []
    assert d.selected_effect == "none"
    assert d.delay_as_read_out is not None and d.delay_as_read_out < 1e-3
    assert d.timing.gyro_average is True
    assert d.rmse_after / d.noise_floor <= CONVERGED_RATIO
