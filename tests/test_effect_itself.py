"""A candidate's gain must come from its effect, not from its refit's rate
parameters (`isp_twin.diagnosis.rounds._effect_itself`)."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.diagnosis.candidates import BASELINE, CandidateFit, holdout_residuals
from isp_twin.diagnosis.residual import noise_floor
from isp_twin.diagnosis.rounds import _effect_itself, _RoundState
from isp_twin.diagnosis.synthetic import excitation, make_run
from isp_twin.estimation.least_squares import FitStatus
from isp_twin.estimation.simulation_error import stack_runs
from isp_twin.model.effects.base import Effect
from isp_twin.model.effects.deadzone import Deadzone
from isp_twin.model.parameters import EffectSpec, load_parameters
from isp_twin.model.substep_model import EQ6
from isp_twin.resources import default_parameters_path

DT = 1e-3
COGGING = {"amplitude_rad_s2": 0.8, "period_rad": 0.12, "phase_rad": 1.0}


class _Held:
    """What `_effect_itself` asks of `DiagnosisData`: held-out residuals."""

    def __init__(self, stack):
        self.stack = stack
        self.train = stack

    def held_residuals(self, fits):
        return holdout_residuals(self.stack, fits)


def _fit(name, params, ci95, x, bic):
    return CandidateFit(
        name=name,
        params=params,
        ci95=ci95,
        rate_vector=x,
        rate_ci95=np.zeros_like(x),
        sse=1.0,
        n_samples=3000,
        n_params=20,
        bic=bic,
        status=FitStatus.CONVERGED,
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_null_effect_on_better_rates_is_overruled_and_a_real_effect_kept(seed):
    """Held-out data with a true cogging; the base has static levels 25 % high.
    'input_delay' at delay 0 on the true rates wins held out only through its
    rates; 'cogging' at the truth wins through the effect."""
    rate = load_parameters(default_parameters_path()).axis("inner_az").rate_params()
    rng = np.random.default_rng(seed)
    truth = EffectSpec("cogging", COGGING)
    runs = [
        make_run(f"h{i}", rate, excitation(rng, 1500, DT), DT, rng, [truth], angle0=0.1)
        for i in range(2)
    ]
    data = _Held(stack_runs(runs, integration=EQ6))
    x_true = rate.to_vector()
    x_base = x_true.copy()
    x_base[2::5] *= 1.25  # static levels
    base = _fit(BASELINE, {}, {}, x_base, 0.0)
    fits = {
        "input_delay": _fit("input_delay", {"delay_s": 0.0}, {"delay_s": 1e-4}, x_true, -50.0),
        "cogging": _fit("cogging", COGGING, {k: 0.01 for k in COGGING}, x_true, -60.0),
    }
    held = data.held_residuals([base, *fits.values()])
    st = _RoundState(
        base, fits, dict(zip(fits, held[1:])), held[0], noise_floor(held[0]), frozenset()
    )
    verdicts = [st.judge(n) for n in fits]
    assert all(v.significant for v in verdicts), verdicts  # against the worse base: both win
    after = {v.name: v for v in _effect_itself(data, st, verdicts)}
    assert not after["input_delay"].significant
    assert "switched off" in after["input_delay"].reason
    assert after["cogging"].significant


def test_a_dead_zone_narrower_than_its_search_is_negligible():
    assert Deadzone.negligible({"width_digits": 0.37}, 900.0)
    assert "below 0.5%" in Deadzone.negligible({"width_digits": 4.4}, 900.0)
    assert Deadzone.negligible({"width_digits": 4.6}, 900.0) == ""
    assert Effect.negligible({}, 900.0) == ""


def test_a_gyro_error_the_angle_does_not_show_is_not_an_answer():
    # The angle measures the gyro's error apart from any rate model: on a
    # clean reference axis it shows none and a sensor_bias candidate is
    # overruled; on an axis with a gyro error it shows one and is not.
    from isp_twin.diagnosis.rounds import _gyro_error_unseen
    from isp_twin.identification.measured import MeasuredData
    from isp_twin.reference import design_experiment

    def runs(effect):
        exp = design_experiment(1000, effect)
        return [
            MeasuredData(n, r.t, r.u, r.omega, r.theta, None, DT)
            for n, r in exp.runs.items()
            if n != "heldout"
        ]

    assert "shows no gyro error" in _gyro_error_unseen(runs(None))
    assert _gyro_error_unseen(runs("sensor_bias")) == ""


def test_a_cogging_period_longer_than_the_travel_is_undetermined():
    from isp_twin.model.effects.cogging import Cogging

    assert "longer than the travel" in Cogging.undetermined({**COGGING, "period_rad": 0.5}, 0.4)
    assert Cogging.undetermined({**COGGING, "period_rad": 0.3}, 0.4) == ""
    assert Effect.undetermined({}, 0.4) == ""


def test_a_cogging_seen_over_less_than_one_period_is_overruled():
    # Against a worse base both win held out; the one whose period is longer
    # than the runs' travel (a smooth torque of the angle, which an unbalance
    # or a spring makes as well) is overruled first, the ripple is kept.
    rate = load_parameters(default_parameters_path()).axis("inner_az").rate_params()
    rng = np.random.default_rng(3)
    truth = EffectSpec("cogging", COGGING)
    runs = [
        make_run(f"h{i}", rate, excitation(rng, 1500, DT), DT, rng, [truth], angle0=0.1)
        for i in range(2)
    ]
    data = _Held(stack_runs(runs, integration=EQ6))
    travel = float(np.ptp(data.train.angle[data.train.mask]))
    assert COGGING["period_rad"] < travel
    x_true = rate.to_vector()
    x_base = x_true.copy()
    x_base[2::5] *= 1.25  # static levels
    base = _fit(BASELINE, {}, {}, x_base, 0.0)
    smooth = {**COGGING, "period_rad": 2.0 * travel}
    fits = {
        "cogging": _fit("cogging", COGGING, {k: 0.01 for k in COGGING}, x_true, -60.0),
    }
    held = data.held_residuals([base, *fits.values()])
    st = _RoundState(
        base, fits, dict(zip(fits, held[1:])), held[0], noise_floor(held[0]), frozenset()
    )
    kept = {v.name: v for v in _effect_itself(data, st, [st.judge("cogging")])}
    assert kept["cogging"].significant
    st.fits["cogging"] = _fit("cogging", smooth, {k: 0.01 for k in smooth}, x_true, -60.0)
    st.held_of["cogging"] = data.held_residuals([st.fits["cogging"]])[0]
    verdict = st.judge("cogging")
    assert verdict.significant  # against the worse base it wins held out
    after = {v.name: v for v in _effect_itself(data, st, [verdict])}
    assert not after["cogging"].significant
    assert "longer than the travel" in after["cogging"].reason
