"""A tentative delay: the read-out `identify` chooses with it held, and
that read-out's other gyro reading with the delay refitted there
(`search._reading_refitted`; docs/diagnosis.md "Stop 59").

Reference input delay seed 379 (covered design; the reference simulator
shares no code with the model; its gyro averages over the sample, the
delay is 8.1 ms). A delay half a sample long at the point reading fits the
training runs almost as well as the true delay at the averaged reading,
and was far worse held out (at the noise since stop 67, see the first
test). `diagnose` fitted it long at the data's read-out,
and `identify` with it held chose the point reading. Seed 379 shaped the
stage: a regression test, not a validation.
"""

from __future__ import annotations

import numpy as np
import pytest
from truth_error import prepared_reference

from isp_twin.diagnosis import search
from isp_twin.diagnosis.candidates import fit_candidates, holdout_residual
from isp_twin.diagnosis.rounds import identify_held
from isp_twin.identification.cost import rmse
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import EffectSpec

SEED = 379
AXIS = "inner_az"
POINT = Timing(0.0, False)
#: Where `diagnose`'s first round left the delay on this axis [s]: long
#: by about half a sample.
LONG_DELAY_S = 0.00868


@pytest.fixture(scope="module")
def case():
    """(the data at the point reading, `identify` there with the long delay
    held, the delay refitted there from it, the held-out run, the truth)."""
    checked, data, _, truth = prepared_reference(SEED, "input_delay", AXIS, POINT, ["input_delay"])
    assert truth["sensors"]["gyro_averaged"]
    long = EffectSpec("input_delay", {"delay_s": LONG_DELAY_S})
    again = identify_held(data, (long,), timing=POINT, generations=0)
    fit = fit_candidates(data.train, again.vector, ["input_delay"], (),
                         starts={"input_delay": dict(long.params)}, max_iter=8)["input_delay"]  # fmt: skip
    return data, again, fit, checked[1][0], truth  # the held-out run as given


def test_at_the_point_reading_the_delay_fits_training_and_held_out(case):
    # Stop 59 found this fit above 10 noise floors held out: a regime's
    # friction shape left far from the others' where the training runs do
    # not test it. Given the others' shape where that fits the training
    # runs better (`candidates._consensus_shapes`, stop 67; seed 379 did
    # not shape that stage), it reads at the noise held out too.
    data, _, fit, _, truth = case
    sigma = truth["sensors"]["gyro_noise_rad_s"]
    held = np.concatenate(holdout_residual(data.held, fit))
    assert np.sqrt(fit.sse / fit.n_samples) <= 1.05 * sigma
    assert np.sqrt(np.mean(held**2)) <= 1.2 * sigma


def test_the_averaged_reading_with_the_delay_refitted_is_chosen(case):
    data, again, fit, heldout, truth = case
    sigma = truth["sensors"]["gyro_noise_rad_s"]
    result = search._reading_refitted(again, fit, data)
    assert result.timing == Timing(0.0, True)
    delay = result.effects[-1].params["delay_s"]
    assert delay == pytest.approx(truth["effects"][0]["params"]["delay_s"], abs=0.5e-3)
    held = rmse(result.rate, [heldout], "measured", 0.1, result.effects, result.timing)
    assert result.cost <= 1.03 * sigma and held <= 1.1 * sigma
