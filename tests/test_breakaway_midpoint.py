"""The sub-step that breaks away takes the sliding friction at its mean rate
(`isp_twin.model.substep_model._breakaway_friction`, with the model's
midpoint friction), as every sliding sub-step does.

The reference simulator (`isp_twin.reference`, no shared code) integrates
Eq. 5 at 10 kHz with its own stick logic. On a fast axis (6 ms) with a steep
Stribeck curve, Ts held over the whole breakaway sub-step left the model's
first sample 1.8 % slow (alpha 23 s/rad; 9 noise sigmas on reference clean
axis 215 with its true parameters; docs/identification.md "Stop 42").
"""

from __future__ import annotations

import numpy as np
import pytest
from truth_error import true_rate_params

from isp_twin.identification.cost import simulate_data
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.model.substep_model import EQ6
from isp_twin.reference import REGIME_NAMES, Axis, RegimeFriction, Sensors, simulate


def _axis(alpha: float) -> Axis:
    # J 0.0375 kg·m^2, eta 5.9 N·m·s/rad (6.4 ms), Ts 8.5 and Tc 3.8 N·m,
    # a drive of 25.5 N·m at 850 digits.
    return Axis(0.0375, 5.9, 0.03, tuple(RegimeFriction(8.5, 3.8, alpha) for _ in REGIME_NAMES))


def _first_samples(alpha: float, integration=None):
    """Noise-free reference and model rates of a step from rest off angle 0."""
    axis = _axis(alpha)
    u = np.full(30, 850.0)
    sensors = Sensors(gyro_noise_rad_s=0.0, gyro_averaged=True, resolver_bits=None)
    r = simulate(axis, u, sensors=sensors, theta0_rad=-0.07, seed=None)
    data = MeasuredData("step", r.t, r.u, r.omega, r.theta, None, 1e-3)
    kw = {} if integration is None else {"integration": integration}
    return r.omega, simulate_data(
        true_rate_params(axis), data, timing=Timing(0.0, True), **kw
    ).omega


@pytest.mark.parametrize("alpha", [10.0, 23.0, 60.0])
def test_the_first_sample_of_a_steep_breakaway_is_the_reference_s(alpha):
    ref, model = _first_samples(alpha)
    rel = np.abs(model[1:4] - ref[1:4]) / ref[1:4]
    assert rel.max() < 2e-3, rel


def test_eq6_keeps_ts_over_the_breakaway_step():
    # One step per sample without midpoint friction (Eq. 6, the twin's
    # identification): the breakaway step is slower than the reference's,
    # by the Stribeck drop it ignores.
    ref, model = _first_samples(23.0, EQ6)
    assert model[1] < ref[1]
