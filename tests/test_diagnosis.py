"""Diagnosis building blocks: noise floor, optimizer, acceptance rule, refits."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.diagnosis.candidates import BASELINE, fit_candidates
from isp_twin.diagnosis.residual import analyse, noise_floor
from isp_twin.diagnosis.selection import judge
from isp_twin.diagnosis.synthetic import excitation, make_run
from isp_twin.errors import DataError
from isp_twin.estimation.intervals import confidence_intervals
from isp_twin.estimation.least_squares import levenberg_marquardt
from isp_twin.estimation.simulation_error import predict, stack_runs
from isp_twin.identification.measured import MeasuredData
from isp_twin.model.parameters import EffectSpec, load_parameters
from isp_twin.model.substep_model import EQ6
from isp_twin.resources import default_parameters_path
from isp_twin.vocabulary import SIDE_R

DT = 1e-3
# The synthetic runs are made by Eq. 6 itself (`axis_model`): the model they
# are fitted with is Eq. 6 (m = 1).


@pytest.fixture(scope="module")
def rate():
    return load_parameters(default_parameters_path()).axis("inner_az").rate_params()


@pytest.mark.parametrize("sigma", [0.001, 0.005])
def test_noise_floor_finds_white_noise_under_a_smooth_signal_with_jumps(sigma):
    rng = np.random.default_rng(3)
    t = np.arange(6000) * DT
    smooth = 0.2 * np.sin(2 * np.pi * 1.5 * t) + 0.05 * np.sin(2 * np.pi * 9 * t)
    smooth[::500] += 0.3  # isolated breakaway-like spikes
    runs = [smooth + rng.normal(0, sigma, t.size), smooth[:3000] + rng.normal(0, sigma, 3000)]
    assert noise_floor(runs) == pytest.approx(sigma, rel=0.05)


def test_levenberg_marquardt_solves_a_nonlinear_least_squares_problem_with_known_optimum():
    t = np.linspace(0, 1, 200)
    truth = np.array([2.0, 3.5, 0.3])

    def model(x):  # (P, 3) -> (P, 200)
        return x[:, :1] * np.exp(-x[:, 1:2] * t) + x[:, 2:3]

    y = model(truth[None])[0]
    fit = levenberg_marquardt(
        lambda x: model(x) - y,
        np.array([1.0, 1.0, 0.0]),
        np.full(3, -10.0),
        np.full(3, 10.0),
        np.ones(3),
        max_iter=50,
        rtol=1e-12,
    )
    np.testing.assert_allclose(fit.x, truth, rtol=1e-5)
    assert fit.sse < 1e-12


def test_levenberg_marquardt_respects_bounds():
    fit = levenberg_marquardt(
        lambda x: x - 5.0,
        np.array([0.0]),
        np.array([-1.0]),
        np.array([2.0]),
        np.ones(1),
        max_iter=20,
    )
    assert fit.x[0] == pytest.approx(2.0)


def test_judge_rejects_a_null_change_and_accepts_a_clear_gain():
    rng = np.random.default_rng(0)
    noise = [rng.normal(0, 0.003, 2000) for _ in range(2)]
    tiny = [n + rng.normal(0, 1e-5, n.size) for n in noise]
    assert not judge("x", noise, tiny, 0.0, -5.0, 0.003).significant
    before = [n + 0.01 * np.sin(np.arange(n.size) / 40) for n in noise]
    v = judge("x", before, noise, 0.0, -100.0, 0.003)
    assert v.significant and v.improvement_z > 2
    # The same gain with a worse BIC is refused.
    assert not judge("x", before, noise, 0.0, 10.0, 0.003).significant


def test_stack_runs_refuses_mixed_sample_periods():
    a = MeasuredData(
        "a", np.arange(100) * 1e-3, np.zeros(100), np.zeros(100), np.zeros(100), None, 1e-3
    )
    b = MeasuredData(
        "b", np.arange(100) * 2e-3, np.zeros(100), np.zeros(100), np.zeros(100), None, 2e-3
    )
    with pytest.raises(DataError, match="b: sample period"):
        stack_runs([a, b])


def test_predict_on_a_stack_equals_one_simulation_per_run(rate):
    from isp_twin.model.axis_model import simulate

    rng = np.random.default_rng(1)
    runs = [
        make_run(f"r{i}", rate, excitation(rng, n, DT), DT, rng) for i, n in enumerate((700, 500))
    ]
    st = stack_runs(runs, integration=EQ6)
    resp = predict(st, np.stack([rate.to_vector()] * 2))
    for i, r in enumerate(runs):
        one = simulate(
            rate, r.u, DT, omega0=st.omega[i, 0], angle0=r.angle[0], angle_measured=r.angle
        )
        np.testing.assert_array_equal(resp.omega[1, i, : len(r.u)], one.omega)


def test_refit_recovers_a_known_effect_from_a_wrong_start(rate):
    rng = np.random.default_rng(4)
    truth = EffectSpec("cogging", {"amplitude_rad_s2": 4.0, "period_rad": 0.12, "phase_rad": 1.0})
    runs = [
        make_run(f"r{i}", rate, excitation(rng, 1500, DT), DT, rng, [truth], angle0=0.1)
        for i in range(2)
    ]
    st = stack_runs(runs, integration=EQ6)
    fits = fit_candidates(st, rate.to_vector(), [BASELINE, "cogging"], max_iter=6)
    got = fits["cogging"].params
    assert got["amplitude_rad_s2"] == pytest.approx(4.0, rel=0.05)
    assert got["period_rad"] == pytest.approx(0.12, rel=0.005)
    assert fits["cogging"].rmse < 1.1 * 0.003 < fits[BASELINE].rmse


def test_analysis_sees_white_residual_for_the_true_model_and_structure_otherwise(rate):
    rng = np.random.default_rng(5)
    truth = EffectSpec("resonance", {"freq_hz": 50.0, "damping_ratio": 0.03, "coupling": 0.2})
    runs = [make_run("r", rate, excitation(rng, 3000, DT), DT, rng, [truth], noise_rad_s=0.002)]
    st = stack_runs(runs, integration=EQ6)
    plain = predict(st, rate.to_vector()[None])
    a = analyse(st, type(plain)(plain.omega[0], plain.angle[0], plain.regime[0]))
    assert not a.white
    assert a.peak_hz == pytest.approx(50.0, abs=3.0)
    assert a.noise_floor == pytest.approx(0.002, rel=0.15)
    with_mode = predict(st, rate.to_vector()[None], fixed=[truth])
    b = analyse(st, type(with_mode)(with_mode.omega[0], with_mode.angle[0], with_mode.regime[0]))
    # Nearly white: the mode's ringing (lag-1 correlation near 1) is gone.
    assert a.acf[0] > 0.5
    assert abs(b.acf[0]) < 0.1
    assert b.acf_outside < a.acf_outside
    assert b.rms == pytest.approx(0.002, rel=0.1)


def test_a_fixed_side_picks_the_regimes_as_a_positive_angle_would(rate):
    from isp_twin.model.axis_model import simulate

    rng = np.random.default_rng(6)
    u = excitation(rng, 800, DT)
    angle = np.linspace(-0.3, 0.3, 800)
    fixed = simulate(rate, u, DT, angle_measured=angle, side=SIDE_R)
    positive = simulate(rate, u, DT, angle_measured=np.abs(angle) + 1.0)
    np.testing.assert_array_equal(fixed.omega, positive.omega)
    assert set(np.unique(fixed.regime[1:])) <= {0, 1}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_reopened_rates_never_fit_worse_and_keep_a_known_cable_spring(rate, seed):
    # The candidate refitted from a base that absorbed the spring into its
    # friction levels, then re-opened from the equation-error start with the
    # spring held (`rounds._reopen_rates`): a re-start is kept only if it fits
    # the training runs better, and the spring stays the one that made the data.
    from isp_twin.diagnosis.rounds import _reopen_rates

    rng = np.random.default_rng(seed)
    truth = EffectSpec("cable_spring", {"stiffness_1_s2": 40.0, "offset_rad_s2": 0.0})
    runs = [
        make_run(f"r{i}", rate, excitation(rng, 1500, DT), DT, rng, [truth], angle0=0.1)
        for i in range(2)
    ]
    st = stack_runs(runs, integration=EQ6)
    base = fit_candidates(st, rate.to_vector(), [BASELINE], max_iter=8)[BASELINE]
    local = fit_candidates(st, base.rate_vector, ["cable_spring"], max_iter=8)["cable_spring"]
    again = _reopen_rates(runs, "measured", local, st, 8)
    assert again.name == "cable_spring"
    assert again.sse <= local.sse < base.sse
    assert again.params["stiffness_1_s2"] == pytest.approx(40.0, rel=0.1)


def test_lm_survives_a_model_that_diverges_near_the_start():
    # A candidate that cannot be simulated beside its start (NaN residuals,
    # or slopes so steep that the SVD of J^T J fails) ends as a fit with no
    # interval for the parameter it cannot move, never as an exception
    # (the single-run diagnose of a reference axis raised LinAlgError).
    t = np.linspace(0.0, 1.0, 200)

    def nan_beside_start(xs):
        out = np.array([x[0] * t - 2.0 * t for x in xs])
        out[xs[:, 1] > 1.0] = np.nan  # the second parameter's step diverges
        return out

    fit = levenberg_marquardt(
        nan_beside_start, np.array([1.0, 1.0]), np.zeros(2), np.full(2, 5.0), np.ones(2)
    )
    assert np.isclose(fit.x[0], 2.0, rtol=1e-3) and fit.x[1] == 1.0
    ci = confidence_intervals(fit.jacobian, fit.residual, [0, t.size]).half_width
    assert np.isfinite(ci[0]) and np.isnan(ci[1])

    def explodes(xs):
        return np.array([np.exp(300.0 * x[0]) * np.sin(np.arange(50.0) * x[1]) for x in xs])

    with np.errstate(over="ignore", invalid="ignore"):  # the test's own model overflows
        fit = levenberg_marquardt(
            explodes, np.array([2.0, 1.0]), np.zeros(2), np.full(2, 3.0), np.ones(2)
        )
        ci = confidence_intervals(fit.jacobian, fit.residual, [0, 50]).half_width
    assert ci.shape == (2,)


def test_a_guess_lowers_the_friction_levels_by_what_it_brings_beyond_the_deficit(rate):
    from isp_twin.diagnosis.candidates import FRICTION_KEPT, _friction_lowered
    from isp_twin.model.effects import effect_class
    from isp_twin.model.parameters import RATE_LAYOUT

    x = rate.to_vector()
    tc = RATE_LAYOUT.column(x, "coulomb")
    guesses = [{"accel_rad_s2": a, "presliding_rad": 1e-3} for a in (0.0, 3.0, 1e6)]
    low = _friction_lowered(x, effect_class("lugre"), guesses, DT, deficit=1.0)
    np.testing.assert_array_equal(low[0], x)  # brings less than the deficit
    np.testing.assert_allclose(RATE_LAYOUT.column(low[1], "coulomb"), tc - 2.0 * DT)
    np.testing.assert_allclose(
        RATE_LAYOUT.column(low[1], "static"), RATE_LAYOUT.column(x, "static") - 2.0 * DT
    )
    np.testing.assert_allclose(RATE_LAYOUT.column(low[2], "coulomb"), FRICTION_KEPT * tc)
    for field in ("pole", "gain", "alpha"):
        np.testing.assert_array_equal(
            RATE_LAYOUT.column(low[2], field), RATE_LAYOUT.column(x, field)
        )
    # An effect without sliding friction leaves the levels alone.
    cog = [{"amplitude_rad_s2": 5.0, "period_rad": 0.1, "phase_rad": 0.0}]
    np.testing.assert_array_equal(_friction_lowered(x, effect_class("cogging"), cog, DT)[0], x)


@pytest.mark.parametrize("missing", [2.0, 6.0])
def test_the_residual_shows_a_coulomb_level_the_model_lacks_as_its_friction_deficit(rate, missing):
    from isp_twin.diagnosis.residual import residual_context
    from isp_twin.model.parameters import RATE_LAYOUT, RateParams

    # The runs' axis has `missing` rad/s^2 more sliding friction in every
    # regime than the model; the residual's innovation shows it against
    # the motion: the deficit is that level, up to what the different
    # Stribeck speeds of model and data add (within 25 %).
    x = rate.to_vector()
    more = x + RATE_LAYOUT.per_field(
        {"pole": 0.0, "gain": 0.0, "static": missing * DT, "coulomb": missing * DT, "alpha": 0.0}
    )
    rng = np.random.default_rng(3)
    runs = [
        make_run(f"r{i}", RateParams.from_vector(more), excitation(rng, 2000, DT), DT, rng)
        for i in range(2)
    ]
    st = stack_runs(runs, integration=EQ6)
    ctx = residual_context(st, x)
    assert ctx.coulomb_rad_s2 == pytest.approx(
        float(np.median(RATE_LAYOUT.column(x, "coulomb"))) / DT
    )
    assert ctx.friction_deficit_rad_s2 == pytest.approx(missing, rel=0.25)
    # The model's own runs show none.
    same = [make_run("s", rate, excitation(rng, 2000, DT), DT, rng)]
    st0 = stack_runs(same, integration=EQ6)
    ctx0 = residual_context(st0, x)
    assert abs(ctx0.friction_deficit_rad_s2) < 0.1 * missing
