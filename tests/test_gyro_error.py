"""Gyro bias and scale measured against the angle (`identification.gyro_error`),
and the constant torque the friction levels imply (`effects.torque_offset.implied_offset`).

The analytic cases build a rate, its exact angle (a gyro averaging over the
sample reads exactly the angle's increment), a known gyro error, noise and
resolver quantization, and check recovery and the intervals' coverage over
many seeds. The reference cases are development seeds of issue 8 (1000,
1001 with a gyro error; 1000 clean): data the model code did not make.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isp_twin.errors import ParameterError
from isp_twin.identification.equation_error import sensor_bias_joint_starts
from isp_twin.identification.gyro_error import (
    GyroError,
    gyro_error_estimate,
    rate_behind_gyro_error,
)
from isp_twin.identification.measured import MeasuredData
from isp_twin.model.effects.torque_offset import implied_offset
from isp_twin.model.parameters import RATE_LAYOUT, EffectSpec, RateParams
from isp_twin.reference import design_experiment

DT = 1e-3


def _run(rng, bias, scale, noise, bits=16, n=6000, averaged=True, name="r"):
    """A two-tone motion and its exact angle; the gyro reads ``bias + (1+scale)``
    times the rate averaged over the sample just ended (`averaged`) or at the
    sample instant."""
    t = np.arange(n) * DT
    w1, w2, phase = 2 * np.pi * rng.uniform(0.3, 1.0), 2 * np.pi * rng.uniform(1.5, 3.0), 1.0
    rate = 0.8 * np.cos(w1 * t) + 0.3 * np.sin(w2 * t + phase)
    angle = 0.8 * np.sin(w1 * t) / w1 - 0.3 * np.cos(w2 * t + phase) / w2 + rng.uniform(-1, 1)
    true = np.concatenate(([rate[0]], np.diff(angle) / DT)) if averaged else rate
    reading = bias + (1.0 + scale) * true + noise * rng.standard_normal(n)
    lsb = 2 * np.pi / 2**bits
    return MeasuredData(name, t, np.zeros(n), reading, np.round(angle / lsb) * lsb, None, DT)


def test_the_gyro_error_of_exact_data_is_recovered_exactly():
    rng = np.random.default_rng(1)
    runs = [_run(rng, 0.01, -0.02, 0.0, bits=40) for _ in range(2)]
    est = gyro_error_estimate(runs)
    assert est.bias_rad_s == pytest.approx(0.01, rel=1e-6)
    assert est.scale == pytest.approx(-0.02, rel=1e-6)
    assert abs(est.timing_samples) < 1e-6


def test_a_point_sampled_gyro_is_read_half_a_sample_late_and_still_recovered():
    rng = np.random.default_rng(2)
    runs = [_run(rng, -0.005, 0.015, 1e-3, averaged=False) for _ in range(2)]
    est = gyro_error_estimate(runs)
    assert est.timing_samples == pytest.approx(-0.5, abs=0.05)
    assert est.bias_rad_s == pytest.approx(-0.005, rel=0.01)
    assert est.scale == pytest.approx(0.015, rel=0.01)


def test_the_intervals_cover_the_truth_at_about_their_level():
    # 60 draws of noise, quantization and error: each 95 % interval must
    # contain the truth in at least 85 % of them (binomial: 95 % coverage
    # gives fewer than 51 of 60 with probability < 0.3 %).
    hits_b = hits_s = 0
    draws = 60
    for seed in range(draws):
        rng = np.random.default_rng(100 + seed)
        b, s = rng.uniform(-0.01, 0.01), rng.uniform(-0.03, 0.03)
        noise = rng.uniform(2e-4, 2e-3)
        runs = [_run(rng, b, s, noise, bits=int(rng.integers(14, 20))) for _ in range(2)]
        est = gyro_error_estimate(runs)
        hits_b += abs(est.bias_rad_s - b) <= est.bias_ci95
        hits_s += abs(est.scale - s) <= est.scale_ci95
    assert hits_b >= 0.85 * draws
    assert hits_s >= 0.85 * draws


def test_an_angle_that_does_not_move_is_refused():
    n = 100
    still = MeasuredData(
        "still", np.arange(n) * DT, np.zeros(n), np.zeros(n), np.zeros(n), None, DT
    )
    with pytest.raises(ParameterError, match="does not move"):
        gyro_error_estimate([still])


def test_rate_parameters_behind_a_gyro_error_undo_what_a_fit_to_the_reading_absorbs():
    # The map of the module doc forwards: a model of the reading has gain and
    # levels x (1+s), the bias as a drive (1-a) b, curve factor / (1+s).
    true = RateParams(
        pole=np.array([0.99, 0.98, 0.985, 0.99]),
        gain=np.array([1e-5, 1.2e-5, 0.9e-5, 1.1e-5]),
        static=np.array([3e-3, 2.5e-3, 2.8e-3, 2.2e-3]),
        coulomb=np.array([2e-3, 1.8e-3, 2.1e-3, 1.5e-3]),
        alpha=np.array([40.0, 30.0, 50.0, 20.0]),
    )
    b, s = 0.02, -0.01
    k, drive = 1 + s, (1 - true.pole) * b
    direction = np.array([1.0, -1.0, 1.0, -1.0])
    of_reading = RateParams(
        pole=true.pole,
        gain=k * true.gain,
        static=k * true.static - direction * drive,
        coulomb=k * true.coulomb - direction * drive,
        alpha=true.alpha / k,
    )
    est = GyroError(b, s, 0.0, 0.0, 0.0, 0.0)
    back = rate_behind_gyro_error(of_reading, est)
    np.testing.assert_allclose(back.to_vector(), true.to_vector(), rtol=1e-12)


def _reference_runs(seed: int, effect: str | None):
    exp = design_experiment(seed, effect)
    runs = [
        MeasuredData(
            n, exp.runs[n].t, exp.runs[n].u, exp.runs[n].omega, exp.runs[n].theta, None, DT
        )
        for n in ("train1", "train2")
    ]
    return runs, exp.truth()


@pytest.mark.parametrize("seed", [1000, 1001])
def test_the_gyro_error_of_reference_axes_is_recovered(seed):
    runs, truth = _reference_runs(seed, "sensor_bias")
    true = truth["effects"][0]["params"]
    est = gyro_error_estimate(runs)
    assert est.bias_rad_s == pytest.approx(true["bias_rad_s"], rel=0.1)
    assert est.scale == pytest.approx(true["scale"], rel=0.1)
    assert 1.0 + est.scale == pytest.approx(1.0 + true["scale"], rel=0.01)
    prior = RateParams.from_vector(np.tile([0.99, 1e-5, 2e-3, 1e-3, 10.0], 4))
    starts = sensor_bias_joint_starts(runs, prior)
    assert len(starts) == 2 and all(s.effect.name == "sensor_bias" for s in starts)


def test_a_clean_reference_axis_shows_no_gyro_error():
    runs, _ = _reference_runs(1000, None)
    est = gyro_error_estimate(runs)
    assert est.contains_null()
    prior = RateParams.from_vector(np.tile([0.99, 1e-5, 2e-3, 1e-3, 10.0], 4))
    assert sensor_bias_joint_starts(runs, prior) == ()


def test_the_offset_implied_by_shifted_levels_is_the_offset_plus_the_asymmetry():
    pole = np.array([0.99, 0.98, 0.985, 0.99])
    h = -np.log(pole) / ((1 - pole) * DT)  # rate per sample -> rad/s^2
    levels = np.array([2.0, 1.6, 2.2, 1.9])  # Tc/J per regime [rad/s^2]
    offset = 0.7
    shifted = levels + np.array([-1, 1, -1, 1]) * offset
    got = implied_offset(pole, shifted / h, np.full(4, 1e-3) / h, DT)
    assert got.right_rad_s2 == pytest.approx(offset + (1.6 - 2.0) / 2, rel=1e-12)
    assert got.left_rad_s2 == pytest.approx(offset + (1.9 - 2.2) / 2, rel=1e-12)
    # Sides 0.05 apart with half-widths ~7e-4: not one constant torque.
    assert not got.consistent
    symmetric = np.array([2.0, 2.0, 1.5, 1.5]) + np.array([-1, 1, -1, 1]) * offset
    got = implied_offset(pole, symmetric / h, np.full(4, 1e-3) / h, DT)
    assert got.consistent
    assert got.value_rad_s2 == pytest.approx(offset, rel=1e-12)
    assert math.isfinite(got.ci95) and got.ci95 > 0


def test_true_rate_inverts_measure():
    from isp_twin.model.effects import make_effect

    rng = np.random.default_rng(5)
    for _ in range(20):
        params = {"bias_rad_s": rng.uniform(-0.02, 0.02), "scale": rng.uniform(-0.05, 0.05)}
        e = make_effect(EffectSpec("sensor_bias", params))
        w = rng.normal(0.0, 1.0, 50)
        np.testing.assert_allclose(e.true_rate(e.measure(w)), w, rtol=0, atol=1e-12)


def test_the_fusion_corrects_the_reading_for_the_error_the_angle_shows():
    # A 3 % scale error leaves s (theta - smooth(theta)) in the fused angle
    # of the raw reading; corrected first, only the quantization is left.
    from isp_twin.identification.side_angle import FUSION_WINDOW, fused_angle

    rng = np.random.default_rng(7)
    run = _run(rng, 0.004, 0.03, 2e-4, bits=19)
    exact = _run(np.random.default_rng(7), 0.0, 0.0, 0.0, bits=60).angle
    integral = np.cumsum(run.omega) * DT
    gap = np.pad(run.angle - integral, FUSION_WINDOW // 2, mode="edge")
    raw_fusion = integral + np.convolve(gap, np.ones(FUSION_WINDOW) / FUSION_WINDOW, "valid")
    lsb = 2 * np.pi / 2**19
    assert np.max(np.abs(fused_angle(run) - exact)) < lsb
    assert np.max(np.abs(raw_fusion - exact)) > 5 * lsb


def test_a_biased_gyro_reading_at_rest_starts_the_model_at_rest():
    # The first reading is b, not a motion: with the sensor_bias effect the
    # model starts at rest (the rest rule on the rate behind the reading)
    # and, stuck under a small command, reads b throughout.
    from isp_twin.estimation.simulation_error import predict_one, stack_runs

    n, b = 500, 0.01
    noise = 1e-4 * np.random.default_rng(3).standard_normal(n)
    run = MeasuredData("rest", np.arange(n) * DT, np.full(n, 0.1), b + noise, np.zeros(n), None, DT)
    x = np.tile([0.99, 1e-3, 5e-3, 4e-3, 10.0], RATE_LAYOUT.n_regimes)
    stack = stack_runs([run], warmup=1, rest=3e-4)
    spec = EffectSpec("sensor_bias", {"bias_rad_s": b, "scale": 0.0})
    with_effect = predict_one(stack, x, (spec,)).omega[0]
    np.testing.assert_allclose(with_effect[1:], b, rtol=0, atol=1e-12)
    assert np.max(np.abs(predict_one(stack, x).omega[0][1:] - b)) > 5e-3
