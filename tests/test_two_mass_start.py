"""identify's start on a two-mass axis (`isp_twin.identification.motor_side`,
`equation_error._payload_rows`): the motor side's rate from the gyro on the
payload and the resolver on the motor, against the exact solution of a
frictionless two-mass axis and the reference simulator's own motor side;
the start's levels against the truth of reference axes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from isp_twin.diagnosis.residual import ResidualContext
from isp_twin.estimation.simulation_error import stack_runs
from isp_twin.identification.cost import rmse
from isp_twin.identification.equation_error import equation_error_estimate
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.motor_side import motor_side_rates, payload_mode
from isp_twin.identification.read_out import Timing
from isp_twin.identification.report import payload_hint
from isp_twin.identification.side_angle import with_side_angle
from isp_twin.model.effects.resonance import Resonance
from isp_twin.model.parameters import RATE_LAYOUT, EffectSpec, RateParams
from isp_twin.reference import design_experiment
from isp_twin.units import DEG

DT = 1e-3


def _two_mass(j: float, frac: float, freq_hz: float, zeta: float, torque: np.ndarray):
    """Exact zero-order-hold solution of a frictionless two-mass axis,
    state (theta1, w1, theta2, w2): the gyro averaged over each sample on
    the payload, the resolver at each sample on the motor, the motor rate."""
    j1, j2 = (1.0 - frac) * j, frac * j
    mu = j1 * j2 / j
    wn = 2.0 * np.pi * freq_hz
    k, c = mu * wn * wn, 2.0 * zeta * mu * wn
    a = np.zeros((5, 5))  # with the held torque as a fifth state
    a[0, 1] = a[2, 3] = 1.0
    a[1] = [-k / j1, -c / j1, k / j1, c / j1, 1.0 / j1]
    a[3] = [k / j2, c / j2, -k / j2, -c / j2, 0.0]
    step = expm(a * DT)[:4]
    x = np.zeros(4)
    states = [x]
    for tau in torque[:-1]:
        x = step @ np.r_[x, tau]
        states.append(x)
    s = np.array(states)
    gyro = np.r_[0.0, np.diff(s[:, 2]) / DT]
    return gyro, s[:, 0], s[:, 1]


def test_the_motor_side_of_a_frictionless_two_mass_axis_is_recovered_from_both_sensors():
    rng = np.random.default_rng(3)
    n = 3000
    torque = np.repeat(rng.uniform(-1.0, 1.0, n // 100), 100)
    mode = {"freq_hz": 30.0, "damping_ratio": 0.04, "coupling": 1.0, "payload_fraction": 0.2}
    gyro, theta, motor = _two_mass(0.04, 0.2, 30.0, 0.04, torque)
    gyro = gyro + rng.normal(0.0, 2e-4, n)
    lsb = 2.0 * np.pi / 2**18
    resolver = np.round(theta / lsb) * lsb
    d = MeasuredData("two_mass", np.arange(n) * DT, torque, gyro, resolver, None, DT)
    est = motor_side_rates(d, EffectSpec("resonance", mode))
    err = np.sqrt(np.mean((est.motor[50:] - motor[50:]) ** 2))
    quotient = np.sqrt(np.mean((np.diff(resolver) / DT - 0.5 * (motor[1:] + motor[:-1])) ** 2))
    ringing = np.sqrt(np.mean((gyro - motor) ** 2))
    # The payload's ringing and the resolver's quantization are both far
    # larger than what the smoother leaves.
    assert err < 0.2 * quotient
    assert err < 0.05 * ringing


@pytest.fixture(scope="module")
def reference():
    """Reference resonance axes 30 and 43 (seed 30 shaped the change)."""
    return {s: design_experiment(s, "resonance") for s in (30, 43)}


@pytest.mark.parametrize("seed", [30, 43])
def test_the_motor_side_of_reference_axes_is_closer_than_either_sensor(reference, seed):
    exp = reference[seed]
    run = exp.runs["train1"]
    params = exp.truth()["effects"][0]["params"]
    d = MeasuredData("train1", run.t, run.u, run.omega, run.theta, None, DT)
    est = motor_side_rates(d, EffectSpec("resonance", params))
    err = np.sqrt(np.mean((est.motor - run.rate) ** 2))
    quotient = np.sqrt(
        np.mean((np.diff(run.theta) / DT - 0.5 * (run.rate[1:] + run.rate[:-1])) ** 2)
    )
    assert err < 0.5 * quotient
    assert err < 0.1 * np.sqrt(np.mean((run.omega - run.rate) ** 2))


@pytest.mark.parametrize("seed", [30, 43])
def test_holding_the_two_mass_mode_brings_the_start_to_the_truths_basin(reference, seed):
    exp = reference[seed]
    truth = exp.truth()
    form = truth["rate_form"]["regimes"]
    x_true = np.array([[form[r][f] for f in RATE_LAYOUT.fields] for r in truth["regime_order"]])
    runs = [
        MeasuredData(n, r.t, r.u, r.omega, r.theta, None, DT)
        for n, r in ((n, exp.runs[n]) for n in ("train1", "train2"))
    ]
    prior = RateParams.from_vector(
        RATE_LAYOUT.from_table(np.tile([0.99, 1e-4, 0.01, 0.005, 1.0], (4, 1)))
    )
    held = [EffectSpec("resonance", truth["effects"][0]["params"])]
    timing = Timing(0.0, truth["sensors"]["gyro_averaged"])
    sigma = truth["noise_sigma_deg_s"] * DEG
    costs, gains = [], []
    for effects in ((), held):
        # Before the motor side was read, holding the mode changed no row:
        # the start was the one without it.
        start = equation_error_estimate(runs, prior, effects=effects)
        costs.append(float(rmse(start, runs, effects=held, timing=timing)) / sigma)
        x = RATE_LAYOUT.as_table(start.to_vector())[:, RATE_LAYOUT.field_index("gain")]
        gains.append(np.median(np.abs(x / x_true[:, RATE_LAYOUT.field_index("gain")] - 1.0)))
    assert gains[0] > 0.5  # read from the gyro: the ringing taken for friction
    assert gains[1] < 0.2
    assert costs[1] < 0.2 * costs[0]


def test_only_a_two_mass_payload_changes_the_rows():
    mode = {"freq_hz": 30.0, "damping_ratio": 0.04, "coupling": 1.0}
    assert payload_mode([EffectSpec("resonance", {**mode, "payload_fraction": 0.0})]) is None
    assert payload_mode([EffectSpec("cogging", {"amplitude": 1.0})]) is None
    held = EffectSpec("resonance", {**mode, "payload_fraction": 0.2})
    assert payload_mode([EffectSpec("cogging", {"amplitude": 1.0}), held]) is held


def _context(effect: str | None, seed: int, fused: bool = True):
    """The training runs of a reference axis as diagnose stacks them (the
    fused angle with the resolver's beside it, or the resolver's alone),
    with a white residual: no peak of its own."""
    exp = design_experiment(seed, effect)
    runs = [
        MeasuredData(n, r.t, r.u, r.omega, r.theta, None, DT)
        for n, r in ((n, exp.runs[n]) for n in ("train1", "train2"))
    ]
    if fused:
        runs = [with_side_angle(r, "measured") for r in runs]
    stack = stack_runs(runs)
    n = stack.n_samples
    flat = stack.flat
    deflection, lines = stack.deflection()
    return exp, ResidualContext(
        u=flat(stack.u),
        angle=flat(stack.angle),
        rate=flat(stack.omega),
        residual=np.random.default_rng(0).normal(0.0, 1e-3, n),
        accel=np.zeros(n),
        moving=np.ones(n, bool),
        run_id=np.zeros(n, int),
        dt=DT,
        deflection_rate=deflection,
        deflection_lines=lines,
    )


@pytest.mark.parametrize("seed, fused", [(30, True), (38, True), (38, False)])
def test_the_resonance_guesses_a_strong_payloads_mode_from_the_sensors(seed, fused):
    exp, ctx = _context("resonance", seed, fused)
    mode = exp.truth()["effects"][0]["params"]
    free = mode["freq_hz"]
    clamped = free * np.sqrt(1.0 - mode["payload_fraction"])
    freqs = {g["freq_hz"] for g in Resonance.guesses(ctx) if g["payload_fraction"] == 0.0}
    assert any(0.9 * clamped <= f <= 1.1 * free for f in freqs)


@pytest.mark.parametrize("effect", [None, "lugre"])
def test_no_deflection_peak_stands_out_without_a_payload(effect):
    _, ctx = _context(effect, 1)
    assert Resonance._deflection_peak(ctx) == []


def _runs(effect: str | None, seed: int):
    exp = design_experiment(seed, effect)
    return [
        MeasuredData(n, r.t, r.u, r.omega, r.theta, None, DT)
        for n, r in ((n, exp.runs[n]) for n in ("train1", "train2"))
    ]


def test_identify_names_the_mode_the_sensors_show():
    hint = payload_hint(_runs("resonance", 30))
    assert "resonance" in hint
    # Between the clamped (22.7 Hz) and the free (25.5 Hz) frequency, or near.
    freq = float(hint.split("near ")[1].split(" Hz")[0])
    assert 0.9 * 22.7 <= freq <= 1.1 * 25.5


@pytest.mark.parametrize("effect", [None, "sensor_bias"])
def test_identify_names_no_mode_without_a_payload(effect):
    assert payload_hint(_runs(effect, 1)) == ""
