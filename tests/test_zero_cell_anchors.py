"""The side of a rest inside the zero reading, from the edges of that reading.

A resolver reading of 0 holds angles of either sign within half its step. An
axis that comes to rest there, off the run's start, has a side the reading
does not give; the fusion's level there is the mean of the quantization
over its window, a fraction of a step off. The edge where the reading
changed is exact to the motion over that sample, and the integrated rate
carries it to the rest (`isp_twin.identification.side_angle.zero_cell_anchors`;
docs/identification.md "Stop 49"). Data from the reference simulator, which
shares no code with the model.
"""

from __future__ import annotations

import numpy as np
from truth_error import true_rate_params

from isp_twin.identification.cost import residuals
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.identification.side_angle import (
    fused_angle,
    resolver_step,
    side_angle,
    zero_cell_anchors,
)
from isp_twin.reference import Axis, RegimeFriction, Sensors, simulate

SIGMA = 1e-3  # gyro noise [rad/s] (0.06 deg/s)
BITS = 15
LSB = 2.0 * np.pi / 2**BITS
SENSORS = Sensors(gyro_noise_rad_s=SIGMA, gyro_averaged=True, resolver_bits=BITS)
REST = slice(60, 340)  # at rest after the first push
RESTART = slice(340, 440)  # the push back from that rest


def _axis() -> Axis:
    # The motor gain differs by side (R 0.8, L 1.3 of Km): a restart on the
    # wrong side's gain leaves an error that decays with the pole.
    return Axis(
        0.02,
        0.2,
        3e-4,
        (
            RegimeFriction(0.15, 0.10, 30.0, 1.0, 0.8),
            RegimeFriction(0.14, 0.10, 30.0, 1.0, 0.8),
            RegimeFriction(0.15, 0.11, 30.0, 1.0, 1.3),
            RegimeFriction(0.16, 0.11, 30.0, 1.0, 1.3),
        ),
    )


def _command() -> np.ndarray:
    # From rest two steps below 0: a push that crosses 0 and stops about a
    # third of a step above it (inside the zero reading), then a push back.
    return np.concatenate([np.full(40, 398.0), np.zeros(300), np.full(300, -700.0)])


def _run(seed: int | None) -> tuple[MeasuredData, np.ndarray]:
    r = simulate(_axis(), _command(), sensors=SENSORS, theta0_rad=-2.0 * LSB, seed=seed)
    return MeasuredData("run", r.t, r.u, r.omega, r.theta, None, 1e-3), r.angle


def test_the_rest_is_inside_the_zero_reading_and_on_the_right():
    data, angle = _run(None)
    assert np.all(data.angle[REST] == 0.0)
    assert np.all((angle[REST] > 0.2 * LSB) & (angle[REST] < 0.45 * LSB))


def test_the_resolver_step_is_read_from_the_readings():
    data, _ = _run(0)
    assert np.isclose(resolver_step(data.angle), LSB, rtol=1e-9)
    # Read back from a file that keeps 10 significant digits of degrees (the
    # benchmark's CSV), far from 0: still the grid. The first version took
    # the smallest gap as the step and asked for 1e-6 steps: it anchored
    # nothing on the benchmark's runs beyond about 1 deg.
    far = data.angle + 10_000 * LSB
    printed = np.radians(np.array([float(f"{v:.10g}") for v in np.degrees(far)]))
    assert np.isclose(resolver_step(printed), LSB, rtol=1e-7)
    assert resolver_step(data.angle + 0.1 * LSB) is None  # off the grid
    assert resolver_step(np.zeros(10)) is None  # one level only


def test_the_anchored_angle_is_the_true_one_within_three_of_its_deviations():
    for seed in range(5):
        data, angle = _run(seed)
        est, sd = zero_cell_anchors(data, data.omega)
        assert np.all(np.isfinite(est[REST]))
        assert np.all(np.abs(est[REST] - angle[REST]) < 3.0 * sd[REST]), seed
        assert np.all(sd[REST] < 0.1 * LSB)  # the rest is at 0.2-0.45 steps
        # The side angle's anchors (from the reading corrected for a gyro error, if any).
        assert np.allclose(fused_angle(data)[REST], est[REST], atol=0.05 * LSB)


def test_the_side_of_the_rest_is_right_and_the_truth_reaches_the_noise_on_the_restart():
    """Over seeds: the rest's side is R, and the truth's error over the push
    back is at the noise (a slow crossing right after the rest leaves a
    fraction of a sample in its timing on some seeds). From the fusion alone
    the rest's side was 0 (the push back's, L) or L on every seed, 12.9-24.4
    noise sigmas over the push back on seeds 0-4 (the code before stop 49)."""
    truth = true_rate_params(_axis())
    errors = []
    for seed in range(8):
        data, _ = _run(seed)
        assert np.all(side_angle(data)[REST] > 0.0), seed
        e = residuals(truth, [data], timing=Timing(0.0, True))
        errors.append(float(np.sqrt(np.mean(e[..., RESTART] ** 2))) / SIGMA)
    assert np.median(errors) < 1.5, errors
    assert max(errors) < 3.0, errors


def test_without_an_angle_on_a_grid_nothing_is_anchored():
    data, _ = _run(0)
    off = MeasuredData("run", data.t, data.u, data.omega, data.angle + 1e-7, None, 1e-3)
    est, sd = zero_cell_anchors(off, off.omega)
    assert not np.isfinite(est).any() and not np.isfinite(sd).any()
