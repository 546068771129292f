"""The points Levenberg-Marquardt only compares among themselves, simulated
apart (`lm_steps(relative=)`, `Relative`: a Jacobian's columns, the static
scan), and diagnose's candidates taking them at fewer sub-steps
(`relative_stack`, `Effect.fine_slopes`; docs/diagnosis.md "Stop 84").

A column is only the slope a step is proposed from, a scan only ranks:
every step and the scan's choice are accepted on the plain residuals, and
the Jacobian the intervals come from is the plain one at the end point.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from truth_error import training_stack, truth_rate_vector

from isp_twin.diagnosis import candidates
from isp_twin.diagnosis.candidates import BASELINE, fit_candidates
from isp_twin.estimation.least_squares import Relative, lm_steps, solve_many
from isp_twin.estimation.simulation_error import JACOBIAN_SUBSTEPS, relative_stack, residuals
from isp_twin.model.effects import EFFECTS, effect_class
from isp_twin.model.parameters import EffectSpec
from isp_twin.model.substep_model import Integration
from isp_twin.reference import design_experiment

RNG = np.random.default_rng(7)
A = RNG.normal(size=(40, 3))
B = A @ np.array([1.0, -2.0, 0.5]) + 0.01 * RNG.normal(size=40)


def _linear(slope_gain: float, seen: list):
    """An evaluator of r(x) = A x - b whose `Relative` model is `slope_gain` times off."""

    def evaluate(reqs):
        out = []
        for _, x in reqs:
            if isinstance(x, Relative):
                seen.append(x.points)
                out.append(slope_gain * (x.points @ A.T - B) + 3.0)
            else:
                out.append(x @ A.T - B)
        return out

    return evaluate


def _fit(relative: bool, slope_gain: float = 1.0, seen=None):
    lo, hi = np.full(3, -10.0), np.full(3, 10.0)
    gen = lm_steps(np.zeros(3), lo, hi, np.ones(3), max_iter=20, relative=relative)
    return solve_many([gen], _linear(slope_gain, [] if seen is None else seen))[0]


def test_the_columns_come_as_one_set_with_their_linearisation_point():
    seen: list = []
    fit = _fit(True, seen=seen)
    assert seen, "no Relative asked for"
    for pts in seen:
        assert pts.shape == (4, 3)
        np.testing.assert_allclose(np.diag(pts[1:] - pts[0]), 1e-3)
    assert not np.any(np.isclose(np.diag(seen[-1][1:] - seen[-1][0]), 0.0))
    np.testing.assert_allclose(fit.x, np.linalg.lstsq(A, B, rcond=None)[0], atol=1e-6)


def test_steps_are_accepted_on_the_plain_residuals_and_the_jacobian_is_the_plain_one():
    # Relative 30 % off and shifted: the slopes are differences within their
    # own set (the shift cancels), the steps still reach the plain optimum.
    fit = _fit(True, slope_gain=1.3)
    np.testing.assert_allclose(fit.residual, fit.x @ A.T - B)
    np.testing.assert_allclose(fit.jacobian, A, rtol=1e-6)
    np.testing.assert_allclose(fit.x, np.linalg.lstsq(A, B, rcond=None)[0], atol=1e-4)
    assert list(fit.sse_log) == sorted(fit.sse_log, reverse=True)


def test_without_relative_nothing_changes():
    seen: list = []
    plain = _fit(False, slope_gain=1.3, seen=seen)
    assert not seen
    np.testing.assert_allclose(plain.x, np.linalg.lstsq(A, B, rcond=None)[0], atol=1e-6)


def _scan_only(relative: bool, evaluate):
    lo, hi = np.full(3, -10.0), np.full(3, 10.0)
    gen = lm_steps(np.full(3, 0.7), lo, hi, np.ones(3), max_iter=0, scan=[0], relative=relative)
    return solve_many([gen], evaluate)[0]


def test_the_scan_ranks_relative_points_against_its_start_among_them():
    seen: list = []
    plain = _scan_only(False, _linear(1.0, []))
    same = _scan_only(True, _linear(1.0, seen))
    assert len(seen) == 1 and np.array_equal(seen[0][0], np.full(3, 0.7))
    assert seen[0].shape == (11, 3)
    np.testing.assert_array_equal(same.x, plain.x)
    assert plain.x[0] != 0.7  # the scan moved it


def test_a_scan_choice_is_kept_only_if_the_plain_residuals_agree():
    def lying(reqs):
        # The relative model ranks the scanned value furthest from the
        # optimum (1.0) best.
        out = []
        for _, x in reqs:
            if isinstance(x, Relative):
                out.append(np.abs(x.points[:, :1] - 0.42) @ np.ones((1, 40)))
            else:
                out.append(x @ A.T - B)
        return out

    fit = _scan_only(True, lying)
    start = np.full(3, 0.7) @ A.T - B
    assert fit.sse <= float(start @ start)
    np.testing.assert_array_equal(fit.x, np.full(3, 0.7))


@pytest.fixture(scope="module")
def stack():
    return training_stack(design_experiment(202, held_out="covered"))


def test_slope_stack_rules(stack):
    assert stack.integration.substeps > JACOBIAN_SUBSTEPS
    coarse = relative_stack(stack, ["cogging"])
    assert coarse.integration.substeps == JACOBIAN_SUBSTEPS
    assert coarse.u is stack.u and coarse.integration.midpoint_friction == (
        stack.integration.midpoint_friction
    )
    assert relative_stack(stack, []) is not None
    assert relative_stack(stack, ["input_delay"]) is None
    assert relative_stack(stack, ["cogging", "resonance"]) is None
    assert relative_stack(stack, ["cogging"], None) is None
    four = relative_stack(stack, [])
    assert relative_stack(four, []) is None  # not below the model's own


def test_fine_slopes_are_the_effects_in_the_substeps_and_the_delay():
    fine = {n for n in EFFECTS if effect_class(n).fine_slopes}
    assert fine == {"input_delay", "resonance", "lugre"}


def _substeps_asked(stack, monkeypatch, names, fixed=()) -> dict:
    asked: dict = {}
    real = candidates.residuals_many

    def recorded(on, requests, fx=()):
        for _, name, _ in requests:
            asked.setdefault(name or BASELINE, set()).add(on.integration.substeps)
        return real(on, requests, fx)

    monkeypatch.setattr(candidates, "residuals_many", recorded)
    x = truth_rate_vector(design_experiment(202, held_out="covered").truth())
    fit_candidates(stack, x, names, fixed, max_iter=1, polish=False)
    return asked


def test_each_candidate_takes_its_columns_where_its_effects_allow(stack, monkeypatch):
    asked = _substeps_asked(stack, monkeypatch, [BASELINE, "cogging", "input_delay", "resonance"])
    m = stack.integration.substeps
    assert asked[BASELINE] == asked["cogging"] == {m, JACOBIAN_SUBSTEPS}
    assert asked["input_delay"] == asked["resonance"] == {m}


def test_a_held_delay_keeps_every_candidates_columns(stack, monkeypatch):
    held = (EffectSpec("input_delay", {"delay_s": 0.002}),)
    asked = _substeps_asked(stack, monkeypatch, [BASELINE, "cogging"], held)
    assert asked[BASELINE] == asked["cogging"] == {stack.integration.substeps}


def test_the_coarse_columns_fit_a_reference_axis_as_well(stack, monkeypatch):
    # Reference clean axis 202 (no benchmark seed), from its true rate form
    # spoiled by 20 % in every friction level: the refit without an effect
    # with 4-sub-step columns ends within 2 % of the sse the model's own
    # columns reach.
    x = truth_rate_vector(design_experiment(202, held_out="covered").truth())
    spoiled = x.copy()
    for field in ("static", "coulomb"):
        idx = list(candidates.RATE_LAYOUT.field_indices(field))
        spoiled[idx] *= 1.2
    coarse = fit_candidates(stack, spoiled, [BASELINE], polish=False)[BASELINE]
    monkeypatch.setattr(candidates, "relative_stack", lambda *a, **k: None)
    fine = fit_candidates(stack, spoiled, [BASELINE], polish=False)[BASELINE]
    assert coarse.sse <= 1.02 * fine.sse
    start = residuals(stack, spoiled[None])[0]
    assert coarse.sse < 0.5 * float(start @ start)


def test_a_fine_integration_below_the_column_count_is_left_alone(stack):
    two = replace(stack, integration=Integration(2))
    assert relative_stack(two, ["cogging"]) is None
