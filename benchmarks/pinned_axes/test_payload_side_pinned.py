"""The stop-35 payload retry on reference resonance seed 93, end to end:
from the true mode, on the fused angle, nothing is adopted (the side turns
it, not the restart), and the retry reads the gyro as the mode held fits it
(`tests/test_payload_side.py` pins the gate and the adoption on the
resolver's side)."""

from __future__ import annotations

import pytest
from test_payload_side import diagnosis_with, seed_93_case

from isp_twin.diagnosis.candidates import fit_candidate
from isp_twin.diagnosis.prepared_runs import given_held
from isp_twin.diagnosis.search import _at_payload_side, _payload_read_out, _prepared, _side_stack
from isp_twin.identification.read_out import Timing
from isp_twin.model.substep_model import DEFAULT_INTEGRATION


@pytest.fixture(scope="module")
def case():
    return seed_93_case()


def test_the_same_retry_on_the_fused_angle_does_not_adopt_it(case):
    """The side is what turns it, not the restart: from the same true mode,
    identified and judged again on the fused angle, the payload stays
    short of the noise and nothing is adopted."""
    data, checked, fit, params, _ = case
    before = given_held(data, data.ax.rate_params().to_vector())
    diag = diagnosis_with(fit, ("resonance",))
    assert _at_payload_side(diag, data, params, before, checked[1], moved=False) is diag


def test_the_retry_reads_the_gyro_as_the_mode_held_fits_it(case):
    """Read at the wrong gyro read-out (point values; the reference's gyro
    averages over the sample), the retry on the raw angle identifies the
    rates with the mode held at both readings and stacks the runs at the
    averaged one, on the same side, the held-out run with them. (On the
    fused angle `identify` chooses the read-out itself.)"""
    fused = False
    _, checked, _, _, mode = case
    point = Timing(0.0, False)
    wrong = _prepared(checked, "measured", 0, DEFAULT_INTEGRATION, point, False, 8, 2)[0]
    side = _side_stack(wrong, checked[1], fused, point)
    fit = fit_candidate(
        side.train, wrong.ax.rate_params().to_vector(), "resonance", start=mode, max_iter=0
    )
    again, there = _payload_read_out(side, fit, checked[1])
    assert again.timing.gyro_average
    assert there.timing.gyro_average and there.train.gyro_average
    assert (there.runs.train[0].resolver is not None) == fused
    assert there.side_source == ("measured" if fused else "raw")
    assert [r.name for r in there.runs.holdout] == ["heldout"]
