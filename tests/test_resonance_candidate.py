"""The two-mass payload as the library's `resonance` (docs/diagnosis.md,
"Stop 18 R"): P parameter sets in one batch of the sub-stepped kernel equal
one set at a time, a parameter file written before ``payload_fraction``
existed still loads (as the gyro-only mode), and the diagnosis holds the
fraction where the model cannot see it (Eq. 6) and fits it where it can."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from isp_twin.diagnosis.candidates import fit_candidate
from isp_twin.diagnosis.synthetic import excitation, make_run
from isp_twin.errors import ParameterError
from isp_twin.estimation.simulation_error import stack_runs
from isp_twin.model.effects import make_effect
from isp_twin.model.effects.batched import make_batched
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    EffectSpec,
    RateParams,
    load_parameters,
    save_parameters,
)
from isp_twin.model.substep_model import EQ6, Integration, simulate_substeps
from isp_twin.reference import design_experiment
from isp_twin.resources import default_parameters_path

DT = 1e-3
OLD = {"freq_hz": 45.0, "damping_ratio": 0.03, "coupling": 0.2}


@pytest.fixture(scope="module")
def params():
    return load_parameters(default_parameters_path())


def _rate_rows(rate: RateParams, p: int) -> RateParams:
    return RateParams.from_vector(np.tile(rate.to_vector(), (p, 1)))


def test_batched_two_mass_sets_equal_one_set_at_a_time_row_by_row(params):
    rate = params.axis("inner_az").rate_params()
    u = excitation(np.random.default_rng(3), 1500, DT)
    sets = {
        "freq_hz": np.array([30.0, 55.0, 80.0]),
        "damping_ratio": np.array([0.01, 0.04, 0.08]),
        "coupling": np.array([1.0, 1.0, 0.3]),
        "payload_fraction": np.array([0.05, 0.3, 0.15]),
    }
    integration = Integration(10)
    batched = simulate_substeps(
        _rate_rows(rate, 3),
        np.tile(u, (3, 1)),
        DT,
        effects=[make_batched("resonance", sets, DT)],
        integration=integration,
        gyro_average=True,
    )
    for i in range(3):
        one = EffectSpec("resonance", {k: float(v[i]) for k, v in sets.items()})
        single = simulate_substeps(
            rate,
            u,
            DT,
            effects=[make_effect(one, DT)],
            integration=integration,
            gyro_average=True,
        )
        np.testing.assert_allclose(batched.omega[i], single.omega, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(batched.angle[i], single.angle, rtol=1e-12, atol=1e-12)
    # The sets differ (the payload does something in the kernel).
    assert np.ptp(batched.omega, axis=0).max() > 1e-3


def test_a_parameter_file_without_payload_fraction_loads_as_the_gyro_only_mode(params, tmp_path):
    ax = params.axis("inner_az")
    old = params.with_axis(
        "inner_az", dataclasses.replace(ax, effects=(EffectSpec("resonance", OLD),))
    )
    path = save_parameters(old, tmp_path / "old.yaml")
    assert "payload_fraction" not in path.read_text()
    loaded = load_parameters(path).axis("inner_az").effects
    assert [e.name for e in loaded] == ["resonance"]
    effect = make_effect(loaded[0], DT)
    assert effect.params == {**OLD, "payload_fraction": 0.0}
    u = excitation(np.random.default_rng(4), 1200, DT)
    rate = ax.rate_params()
    for integration in (EQ6, Integration(10)):
        got = simulate_substeps(rate, u, DT, effects=[effect], integration=integration)
        gyro_only = make_effect(EffectSpec("resonance", {**OLD, "payload_fraction": 0.0}), DT)
        want = simulate_substeps(rate, u, DT, effects=[gyro_only], integration=integration)
        np.testing.assert_array_equal(got.omega, want.omega)
    # Eq. 6 (the hooks) does not see a payload fraction: the old mode is unchanged there.
    payload = make_effect(EffectSpec("resonance", {**OLD, "payload_fraction": 0.3}), DT)
    eq6 = [simulate_substeps(rate, u, DT, effects=[e], integration=EQ6) for e in (payload, effect)]
    np.testing.assert_array_equal(eq6[0].omega, eq6[1].omega)


def test_an_unknown_resonance_parameter_is_still_an_error():
    with pytest.raises(ParameterError, match="unknown parameter 'fraction'"):
        make_effect(EffectSpec("resonance", {**OLD, "fraction": 0.1}), DT)
    with pytest.raises(ParameterError, match="missing parameter 'coupling'"):
        make_batched("resonance", {"freq_hz": 40.0, "damping_ratio": 0.05}, DT)
    for f in (1.0, -0.1, float("nan")):
        with pytest.raises(ParameterError, match="payload_fraction must be in") as caught:
            make_effect(EffectSpec("resonance", {**OLD, "payload_fraction": f}), DT)
        assert "\n" not in str(caught.value)
    batch = {k: np.full(3, v) for k, v in OLD.items()}
    with pytest.raises(ParameterError, match="got 1.5"):
        make_batched("resonance", {**batch, "payload_fraction": np.array([0.1, 1.5, 0.2])}, DT)


@pytest.mark.parametrize("integration", [EQ6, Integration(10)])
def test_the_fit_holds_the_payload_fraction_only_where_the_model_cannot_see_it(params, integration):
    rng = np.random.default_rng(5)
    rate = params.axis("inner_az").rate_params()
    truth = EffectSpec("resonance", {**OLD, "coupling": 1.0, "payload_fraction": 0.2})
    runs = [make_run(f"run{i}", rate, excitation(rng, 800, DT), DT, rng, [truth]) for i in range(2)]
    stack = stack_runs(runs, integration=integration)
    start = dict(truth.params)
    fit = fit_candidate(stack, rate.to_vector(), "resonance", start=start, max_iter=2)
    assert set(fit.params) == set(truth.params)
    if integration.substeps == 1:
        assert fit.held == ("payload_fraction",)
        assert fit.params["payload_fraction"] == 0.0
        assert np.isnan(fit.ci95["payload_fraction"])
    else:
        assert fit.held == ()
        assert np.isfinite(fit.ci95["payload_fraction"])
    assert fit.rate_vector.shape == (RATE_LAYOUT.size,)


def test_a_null_resonance_row_is_a_rigid_row_bit_for_bit():
    """The diagnosis simulates every candidate in one batch, each row with
    the other candidates' effects at their null parameters: a resonance row
    with coupling 0 and no payload must then be the rigid axis exactly,
    through stops and breakaways (split reversals) too. It was not: a stop
    ended the sub-step on every row of a batch holding a resonance, which
    moved the other candidates' fits (two false positives on clean
    benchmark axes, docs/diagnosis.md "Stop 18"). A clean reference axis's
    run and true rate form (dev seed 1000)."""
    exp = design_experiment(1000)
    truth = exp.truth()
    regimes = truth["rate_form"]["regimes"]
    rate = RateParams.from_vector(
        np.concatenate([[regimes[r][f] for f in RATE_LAYOUT.fields] for r in truth["regime_order"]])
    )
    u = exp.runs["train1"].u
    integration = Integration(10)
    rigid = simulate_substeps(rate, u, DT, integration=integration, gyro_average=True)
    spec = EffectSpec("resonance", {**OLD, "coupling": 0.0})
    null = {k: np.array([v]) for k, v in make_effect(spec, DT).params.items()}
    with_null = simulate_substeps(
        _rate_rows(rate, 1),
        u[None],
        DT,
        effects=[make_batched("resonance", null, DT)],
        integration=integration,
        gyro_average=True,
    )
    assert np.any(rigid.omega == 0.0) and np.any(rigid.omega != 0.0)  # it stops and moves
    np.testing.assert_array_equal(with_null.omega[0], rigid.omega)
