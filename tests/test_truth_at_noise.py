"""The model with a reference axis' *true* parameters reaches the noise.

What no fit can do better than: the sub-stepped model (`DEFAULT_INTEGRATION`)
run with the reference's true rate form and true effect on the reference's
own runs (`isp_twin.reference`, code that shares nothing with the model),
RMS error over the gyro noise per run. Three model details decide it (stop
20, docs/diagnosis.md "Stop 20"):

* a biased gyro's first reading is not a motion: the initial state is the
  reading mapped back through the sensor error (`Effect.true_rate`), then
  the rest rule;
* the angle fusion corrects the reading for the gyro error the angle shows
  (`gyro_error.reading_error`), else a scale error moves fast zero crossings;
* a torque of the angle is taken at the step's mean angle
  (`Integration.midstep_angle`), else a spring or cogging lags half a sample;
* at rest the motor gain is the one of the regime the total drive breaks
  towards (`Integration.rest_drive_gain`, stop 21), not of the command's
  sign: they differ where a spring opposes the command.

The seeds are development seeds (1000-1009) the choices were not made on
(benchmark seeds 0-5 shaped them), and for the rest rule benchmark seed 17
of the cable spring (seed 3 shaped it; 17 was first run after it was
written); each case fails with the detail undone.
"""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.identification.cost import rmse
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import RATE_LAYOUT, EffectSpec, RateParams
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.reference import design_experiment
from isp_twin.units import DEG

#: What "at the noise" means for one run with the true parameters.
AT_NOISE = 1.3


def _truth_errors(seed: int, effect: str, integration: Integration = DEFAULT_INTEGRATION):
    """Per run (train1, train2, held-out): RMS error of the true model / noise sigma."""
    exp = design_experiment(seed, effect)
    truth = exp.truth()
    sigma = truth["noise_sigma_deg_s"] * DEG
    regimes = truth["rate_form"]["regimes"]
    x = np.concatenate([[regimes[r][f] for f in RATE_LAYOUT.fields] for r in truth["regime_order"]])
    spec = (EffectSpec(effect, truth["effects"][0]["params"]),)
    timing = Timing(0.0, truth["sensors"]["gyro_averaged"])
    out = []
    for name in ("train1", "train2", "heldout"):
        r = exp.runs[name]
        data = [MeasuredData(name, r.t, r.u, r.omega, r.theta, None, r.t[1] - r.t[0])]
        err = rmse(
            RateParams.from_vector(x), data, effects=spec, timing=timing, integration=integration
        )
        out.append(float(err) / sigma)
    return out


@pytest.mark.parametrize("seed", [1000, 1008])
def test_a_biased_gyro_with_its_true_error_reaches_the_noise(seed):
    # Before stop 20: 1.16-1.28 (seed 1000) and 10.7 / 4.0 / 1.05 (seed 1008).
    assert max(_truth_errors(seed, "sensor_bias")) <= AT_NOISE


@pytest.mark.parametrize("seed", [1001, 1004])
def test_a_true_cogging_reaches_the_noise_only_at_the_mid_step_angle(seed):
    assert max(_truth_errors(seed, "cogging")) <= AT_NOISE
    start_of_step = Integration(midstep_angle=False)
    assert max(_truth_errors(seed, "cogging", start_of_step)) > AT_NOISE


def test_a_true_cable_spring_reaches_the_noise_only_with_the_rest_gain_of_the_drive():
    assert max(_truth_errors(17, "cable_spring")) <= AT_NOISE
    command_sign = Integration(rest_drive_gain=False)
    assert max(_truth_errors(17, "cable_spring", command_sign)) > AT_NOISE
