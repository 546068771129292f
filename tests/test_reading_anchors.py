"""The angle inside every resolver reading, from the edges of that reading.

A torque of the angle (cogging of a 0.05 rad period) turns an error of the
angle the model is driven by into a drive error. The fusion's level (the
mean of the quantization over its window) is a fraction of a step off at a
rest; the edges where the reading entered and left the reading the axis
rests in are exact to the motion over that sample, and the integrated rate
carries them to the rest (`isp_twin.identification.side_angle.anchored_angle`:
`reading_anchors` weighed with the fusion by `fusion_level_variance`; the
model's torques of the angle read it, `RunStack.torque_angle`;
docs/identification.md "Stop 80"). Data from the reference simulator, which shares no code with
the model.
"""

from __future__ import annotations

import numpy as np
from reference_axes import FAST_AXIS
from truth_error import true_rate_params

from isp_twin.identification.cost import rmse
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.identification.side_angle import (
    FUSION_WINDOW,
    anchored_angle,
    fused_angle,
    fusion_level_variance,
    fusion_noise,
)
from isp_twin.model.parameters import EffectSpec
from isp_twin.reference import Sensors, simulate
from isp_twin.reference.effects import Cogging

AXIS = FAST_AXIS  # 5.2 ms time constant
INERTIA = AXIS.inertia_kg_m2
COGGING = Cogging(0.12, 0.0528, 0.06)  # as strong as the Coulomb levels
SIGMA = 2.5e-4  # gyro noise [rad/s] (0.014 deg/s)
BITS = 14
LSB = 2.0 * np.pi / 2**BITS
SENSORS = Sensors(gyro_noise_rad_s=SIGMA, gyro_averaged=True, resolver_bits=BITS)
SEEDS = range(6)


def _run(seed: int):
    # A 1 Hz cosine with an offset: stick-slip, a third of the time at rest
    # inside readings off 0, held there by the cogging's wells.
    t = np.arange(4000) * 1e-3
    u = 150.0 + 700.0 * np.cos(2.0 * np.pi * t)
    r = simulate(AXIS, u, [COGGING], SENSORS, seed=seed)
    return MeasuredData("run", r.t, r.u, r.omega, r.theta, None, 1e-3), r


def test_at_rest_inside_a_reading_the_angle_is_the_true_one_to_a_tenth_of_a_step():
    for seed in SEEDS:
        data, r = _run(seed)
        rest = (r.regime < 0) & (r.theta != 0.0)
        assert rest.mean() > 0.2, seed  # the case exists
        anchored = np.abs(anchored_angle(data) - r.angle)[rest]
        fused = np.abs(fused_angle(data) - r.angle)[rest]
        assert anchored.max() < 0.1 * LSB, (seed, anchored.max() / LSB)
        # The side angle's fusion (anchored in the zero reading alone): its
        # level is a fraction of a step off at these rests (0.4 steps).
        assert fused.max() > 0.2 * LSB, (seed, fused.max() / LSB)


def test_the_true_cogging_axis_reaches_the_noise():
    """With its true parameters the model of this axis reads the cogging at
    the anchored angle: within 1.3 noise sigmas on every seed (1.64-1.69 at
    the fusion's level, the code before stop 80)."""
    spec = EffectSpec(
        "cogging",
        {
            "amplitude_rad_s2": COGGING.amplitude_nm / INERTIA,
            "period_rad": COGGING.period_rad,
            "phase_rad": COGGING.phase_rad,
        },
    )
    truth = true_rate_params(AXIS)
    errors = []
    for seed in SEEDS:
        data, _ = _run(seed)
        errors.append(float(rmse(truth, [data], effects=(spec,), timing=Timing(0.0, True))) / SIGMA)
    assert max(errors) < 1.3, errors


def _data(angle: np.ndarray) -> MeasuredData:
    n = angle.size
    rng = np.random.default_rng(0)
    t = np.arange(n) * 1e-3
    return MeasuredData("run", t, np.zeros(n), SIGMA * rng.standard_normal(n), angle, None, 1e-3)


def test_the_fusion_level_variance_of_a_rest_is_one_quantization_error():
    data = _data(np.full(1000, 3.0 * LSB))
    v = fusion_level_variance(data, LSB)
    assert np.allclose(v, LSB**2 / 12.0 + fusion_noise(data) ** 2)


def test_the_fusion_level_variance_of_a_new_reading_each_sample_is_averaged_over_the_window():
    data = _data(np.arange(1000) * LSB)
    v = fusion_level_variance(data, LSB)
    expected = LSB**2 / 12.0 / FUSION_WINDOW + fusion_noise(data) ** 2
    assert np.allclose(v, expected)
