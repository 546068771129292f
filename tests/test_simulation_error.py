"""The estimation engine's simulation error and local solvers, shared by
identify and diagnose (`isp_twin.estimation.simulation_error`,
`isp_twin.estimation.least_squares`; docs/identification.md, "Estimation engine")."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from isp_twin.estimation.least_squares import FitStatus, trust_region
from isp_twin.estimation.simulation_error import residuals, residuals_many, stack_runs
from isp_twin.identification.cost import residuals as eq9_residuals
from isp_twin.identification.cost import rmse, run_stack
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.side_angle import with_side_angle
from isp_twin.model.effects import EFFECTS
from isp_twin.model.parameters import RateParams
from isp_twin.units import DEG


@pytest.fixture(scope="module")
def runs_and_rate(paper_params):
    """Two short runs of a paper-like axis (Eq. 7 commands, made in code) and its rate form."""
    rate = paper_params.axis("inner_az").rate_params()
    dt = 1e-3
    t = np.arange(1500) * dt
    out = []
    for i, (amp, off) in enumerate(((750.0, 0.0), (600.0, -100.0))):
        u = amp * np.cos(2 * np.pi * 1.0 * t) + off
        # Any rate/angle pair will do for the properties below; a smooth one.
        omega = 0.2 * np.sin(2 * np.pi * t) * (i + 1)
        angle = np.cumsum(omega) * dt - 0.01
        out.append(MeasuredData(f"run{i}", t, u, omega, angle, None, dt))
    return out, rate


def _spread(rate: RateParams, n: int) -> np.ndarray:
    """n different rate vectors around `rate` (rows), the first `rate` itself."""
    rng = np.random.default_rng(3)
    base = rate.to_vector()
    return base[None] * (
        1.0 + 0.05 * rng.standard_normal((n, base.size)) * (np.arange(n) > 0)[:, None]
    )


def test_a_cost_does_not_depend_on_the_batch_it_is_in(runs_and_rate):
    """The residuals of a parameter set alone and as one row of a batch of
    different sets are the same numbers, and so is their sum of squares
    (the search compares costs computed both ways)."""
    runs, rate = runs_and_rate
    stack = stack_runs(runs, warmup=1)
    batch = _spread(rate, 5)
    together = residuals(stack, batch)
    for k in range(batch.shape[0]):
        alone = residuals(stack, batch[k : k + 1])
        np.testing.assert_array_equal(alone[0], together[k])
        assert float(alone[0] @ alone[0]) == float(together[k] @ together[k])


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_an_effect_at_its_null_parameters_changes_no_bit(runs_and_rate, name):
    """Every library effect at its ``null`` parameters gives the residuals of
    the model without it, bit for bit: what lets `residuals_many` simulate
    each request with its own effect alone."""
    runs, rate = runs_and_rate
    stack = stack_runs(runs, warmup=1)
    batch = _spread(rate, 3)
    cls = EFFECTS[name]
    null = {p: np.full(3, float(cls.null[p])) for p in cls.param_names}
    np.testing.assert_array_equal(residuals(stack, batch, [(name, null)]), residuals(stack, batch))


def test_requests_with_different_effects_are_each_their_own_model(runs_and_rate):
    """`residuals_many` returns, per request, the residuals of that request's
    rate vectors with its own effect alone, in the order asked."""
    runs, rate = runs_and_rate
    stack = stack_runs(runs, warmup=1)
    batch = _spread(rate, 4)
    cog = {"amplitude_rad_s2": np.array([3.0, 5.0]), "period_rad": np.array([0.1, 0.2])}
    cog.update({p: np.array([0.0, 0.0]) for p in EFFECTS["cogging"].param_names if p not in cog})
    off = {"accel_rad_s2": np.array([2.0])}
    requests = [
        (batch[:2], "cogging", cog),
        (batch[2:3], None, {}),
        (batch[3:], "torque_offset", off),
    ]
    got = residuals_many(stack, requests)
    np.testing.assert_array_equal(got[0], residuals(stack, batch[:2], [("cogging", cog)]))
    np.testing.assert_array_equal(got[1], residuals(stack, batch[2:3]))
    np.testing.assert_array_equal(got[2], residuals(stack, batch[3:], [("torque_offset", off)]))
    assert not np.array_equal(got[0][0], residuals(stack, batch[:1])[0])


def test_identify_counts_every_sample_after_the_first_and_diagnose_leaves_a_warmup(runs_and_rate):
    runs, rate = runs_and_rate
    n_total = sum(len(r) for r in runs)
    assert eq9_residuals(rate, runs).size == n_total - len(runs)
    assert stack_runs(runs, warmup=50).n_samples == n_total - 50 * len(runs)


def test_identify_is_the_engine_with_its_own_options(runs_and_rate):
    """Eq. 9's residual is the engine's (sign: simulated minus measured) on
    identify's stack, and a run given as a stack gives the same numbers."""
    runs, rate = runs_and_rate
    stack = run_stack(runs)
    e_engine = residuals(stack, rate.to_vector()[None])[0]
    np.testing.assert_array_equal(eq9_residuals(rate, runs), -e_engine)
    np.testing.assert_array_equal(eq9_residuals(rate, stack), -e_engine)


def test_the_rest_rule_decides_the_initial_state(runs_and_rate):
    """A first rate within the rest level starts the model at rest, above it
    at the measured rate; the noise rule (rest=None) calls a first rate of
    many noise sigmas motion."""
    runs, _ = runs_and_rate
    r = runs[0]
    moving = replace(r, omega=np.concatenate([[0.05], r.omega[1:]]))
    assert stack_runs([moving], rest=0.1 * DEG).omega[0, 0] == 0.05
    assert stack_runs([moving], rest=5.0 * DEG).omega[0, 0] == 0.0
    rng = np.random.default_rng(0)
    noisy = replace(r, omega=np.concatenate([[0.05], 1e-4 * rng.standard_normal(len(r) - 1)]))
    assert stack_runs([noisy], rest=None).omega[0, 0] == 0.05


def test_a_first_reading_within_the_noise_is_rest_whatever_the_fixed_level(runs_and_rate):
    """identify's fixed level (0.1 deg/s) below three noise sigmas: a first
    reading of 0.15 deg/s on a gyro of 0.07 deg/s is noise, so rest."""
    runs, _ = runs_and_rate
    r = runs[0]
    sigma = 0.07 * DEG
    noise = sigma * np.random.default_rng(1).standard_normal(len(r.u))
    noisy = replace(r, omega=np.concatenate([[0.15 * DEG], noise[1:]]))
    assert stack_runs([noisy], rest=0.1 * DEG).omega[0, 0] == 0.0
    far = replace(noisy, omega=np.concatenate([[0.5 * DEG], noise[1:]]))
    assert stack_runs([far], rest=0.1 * DEG).omega[0, 0] == 0.5 * DEG


def test_a_slow_reference_axis_starts_at_rest_under_a_noisy_first_reading():
    """The reference simulator (no shared code) from rest on a 0.5 s axis,
    gyro noise 0.07 deg/s: where the first reading is above 0.1 deg/s, the
    true parameters still reach the noise over the first 0.5 s (the first
    reading as the initial state left 1.8 sigmas there on reference clean
    axis 194's train1)."""
    from truth_error import true_rate_params

    from isp_twin.identification.read_out import Timing
    from isp_twin.reference import REGIME_NAMES, Axis, RegimeFriction, Sensors, simulate

    axis = Axis(0.05, 0.1, 3e-4, tuple(RegimeFriction(0.1, 0.06, 5.0) for _ in REGIME_NAMES))
    truth = true_rate_params(axis)
    sigma = 0.07 * DEG
    t = np.arange(1000) * 1e-3
    u = 900.0 * np.cos(2 * np.pi * t)
    sensors = Sensors(gyro_noise_rad_s=sigma, gyro_averaged=True, resolver_bits=16)
    tried = 0
    for seed in range(40):
        r = simulate(axis, u, sensors=sensors, theta0_rad=-0.1, seed=seed)
        if abs(r.omega[0]) <= 0.1 * DEG:
            continue
        tried += 1
        data = MeasuredData("run", r.t, r.u, r.omega, r.theta, None, 1e-3)
        e = eq9_residuals(truth, [data], timing=Timing(0.0, True))[:500]
        assert np.sqrt(np.mean(e**2)) / sigma < 1.2, seed
    assert tried >= 5


def test_a_diverging_parameter_set_loses_instead_of_giving_nan(runs_and_rate):
    """A pole outside the unit circle makes the model blow up: the cost is
    large and finite (the searches compare it), in identify's Eq. 9 too."""
    runs, rate = runs_and_rate
    bad = rate.to_vector().copy()
    bad[0] = 1.5  # the first regime's pole a
    from isp_twin.model.parameters import RATE_LAYOUT

    assert RATE_LAYOUT.fields[0] == "pole"
    cost = rmse(RateParams.from_vector(np.vstack([rate.to_vector(), bad])), runs)
    assert np.all(np.isfinite(cost)) and cost[1] > 100 * cost[0]


def test_trust_region_recovers_an_exponential_and_reports_a_spent_budget():
    """y = 2 exp(-3 t) + noise: the solver finds (2, 3) within the noise's
    reach; with a budget of 2 evaluations it stops with the budget spent."""
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 2.0, 400)
    y = 2.0 * np.exp(-3.0 * t) + 1e-3 * rng.standard_normal(t.size)

    def resid(p):
        return p[0] * np.exp(-p[1] * t) - y

    def jac(p):
        e = np.exp(-p[1] * t)
        return np.column_stack([e, -p[0] * t * e])

    lo, hi = np.array([0.0, 0.0]), np.array([10.0, 10.0])
    fit = trust_region(resid, jac, np.array([1.0, 1.0]), lo, hi, 200, 1e-10)
    assert fit.status is FitStatus.CONVERGED
    np.testing.assert_allclose(fit.x, [2.0, 3.0], rtol=5e-3)
    assert fit.sse == pytest.approx(float(resid(fit.x) @ resid(fit.x)))
    short = trust_region(resid, jac, np.array([1.0, 1.0]), lo, hi, 2, 1e-10)
    assert short.status is FitStatus.MAX_ITERATIONS


def test_a_stack_follows_the_gyro_only_with_the_fused_angle(runs_and_rate):
    # The sub-stepped model takes a payload's deflection off a side angle
    # that follows the gyro (the fused one), not off the raw resolver's
    # motor-side angle, which diagnose keeps where it fits the start better.
    raw, _ = runs_and_rate
    fused = [with_side_angle(r, "measured") for r in raw]
    assert not stack_runs(raw).side_follows_gyro
    assert stack_runs(raw).resolver_side is None
    stack = stack_runs(fused)
    assert stack.side_follows_gyro
    assert stack.resolver_side.shape == stack.u.shape
    assert stack_runs(raw, side_follows_gyro=True).side_follows_gyro
