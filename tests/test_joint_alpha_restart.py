"""On a fit above `NEAR_NOISE`, every regime's alpha is stepped up and down at
once and the least squares run again, first with the alphas held
(`every_alpha_stepped`, `fit._joint_alpha_restarts`; docs/identification.md
"Stop 55").

Reference clean seed 353 (a 6.6 ms axis, the benchmark's held-out design)
shaped the stage and its factor: identify stopped with R- and L+ at 0.42
and 0.48 of the truth's alpha, 3.1/4.6 truth sigmas on the training runs
(the truth reads 1.02/1.06), and neither the stepped alphas with the rest
kept nor differential evolution left that basin. The tests below pin that
axis and the stage's rules; they do not validate it (the docs' fresh seeds
do).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from identified_runs import identified_reference

from isp_twin.identification import fit
from isp_twin.identification.fit import Settings
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.search_space import (
    ALPHA_JOINT_STEP,
    alpha_positions,
    every_alpha_stepped,
    free_parameters,
)
from isp_twin.model.parameters import RATE_LAYOUT, load_parameters
from isp_twin.reference import design_experiment
from isp_twin.resources import default_parameters_path

N = RATE_LAYOUT.n_fields


def test_the_joint_step_moves_every_alpha_by_the_factor_and_nothing_else():
    z = np.arange(3 * N, dtype=float) / 7.0
    stepped = every_alpha_stepped(z, ALPHA_JOINT_STEP)
    moved = stepped != z
    np.testing.assert_array_equal(moved, alpha_positions(z.size))
    assert np.flatnonzero(moved).tolist() == [4, N + 4, 2 * N + 4]
    np.testing.assert_allclose(np.exp(stepped[moved] - z[moved]), ALPHA_JOINT_STEP)
    np.testing.assert_allclose(every_alpha_stepped(stepped, 1.0 / ALPHA_JOINT_STEP), z)


class _Search(SimpleNamespace):
    """The parts of `fit._Search` the stage reads; records the refinements.
    A held refinement moves z by 0.5; a free one ends at the next of
    `after`'s costs (else the current best)."""

    def refine(self, z, budget, held=None):
        self.calls.append((z.copy(), budget, None if held is None else held.copy()))
        if held is not None:
            self.last_refinement = "held"
            return z + 0.5, self.best_cost, "held"
        self.last_refinement = "free"
        cost = self.after.pop(0) if self.after else self.best_cost
        return z + 1.0, cost, "free"

    def record(self, stage):
        self.recorded.append(stage)


def _search(cost, restart_at_noise=True, after=()):
    return _Search(
        s=Settings(restart_at_noise=restart_at_noise),
        refining=True,
        noise=1.0,
        best_cost=cost,
        z_best=np.zeros(4 * N),
        z_lo=np.full(4 * N, -10.0),
        z_hi=np.full(4 * N, 10.0),
        calls=[],
        recorded=[],
        status_parts=[],
        last_refinement="before",
        after=list(after),
    )


@pytest.mark.parametrize("cost", [1.0, fit.NEAR_NOISE, fit.JOINT_ALPHA_REACH * 1.01])
def test_no_joint_step_at_the_noise_or_far_from_it(cost):
    search = _search(cost)
    fit._joint_alpha_restarts(search)
    assert search.calls == [] and search.status_parts == []


def test_no_joint_step_in_fits_that_skip_the_restarts_at_the_noise():
    search = _search(4.0, restart_at_noise=False)
    fit._joint_alpha_restarts(search)
    assert search.calls == []


@pytest.mark.parametrize("cost", [1.1, 4.0, fit.JOINT_ALPHA_REACH])
def test_above_near_noise_both_steps_are_fitted_with_the_alphas_held_then_freed(cost):
    search = _search(cost)
    fit._joint_alpha_restarts(search)
    held_calls, free_calls = search.calls[0::2], search.calls[1::2]
    assert len(held_calls) == len(free_calls) == 2
    for (z, budget, held), factor in zip(held_calls, (ALPHA_JOINT_STEP, 0.5)):
        assert budget == fit.HELD_ALPHA_EVALUATIONS
        np.testing.assert_array_equal(held, alpha_positions(4 * N))
        np.testing.assert_allclose(z, every_alpha_stepped(np.zeros(4 * N), factor))
    # Each free refinement starts where its held one ended, with the budget.
    for (z, budget, held), (z_held, _, _) in zip(free_calls, held_calls):
        assert held is None and budget == Settings().refine_evaluations
        np.testing.assert_allclose(z, z_held + 0.5)


def test_a_restart_is_kept_only_where_it_gains_more_than_the_margin():
    gain = fit.JOINT_ALPHA_GAIN
    # x2 gains 25 %: kept; x0.5 gains half the margin on that: not kept.
    search = _search(4.0, after=[3.0, 3.0 * (1 - gain / 2)])
    fit._joint_alpha_restarts(search)
    assert search.best_cost == 3.0
    np.testing.assert_allclose(search.z_best, every_alpha_stepped(np.zeros(4 * N), 2.0) + 1.5)
    assert search.status_parts[0].endswith("kept)")
    assert "not kept" in search.status_parts[1]
    assert search.last_refinement == "free"  # the kept one's
    search = _search(4.0, after=[4.0 * (1 - gain / 2), 4.0])
    fit._joint_alpha_restarts(search)
    assert search.best_cost == 4.0
    np.testing.assert_array_equal(search.z_best, np.zeros(4 * N))
    assert search.last_refinement == "before"  # as if the stage had not run


def _data(exp, name: str) -> MeasuredData:
    r = exp.runs[name]
    return MeasuredData(name, r.t, r.u, r.omega, r.theta, None, r.t[1] - r.t[0])


def test_a_held_refinement_keeps_the_held_variables_and_lowers_the_cost():
    exp = design_experiment(353, None, held_out="covered")
    train = [_data(exp, "train1"), _data(exp, "train2")]
    prior = load_parameters(default_parameters_path()).axis("inner_az")
    settings = Settings()
    free = free_parameters(train, prior, settings)
    search = fit._Search(train, free, settings, (), None)
    start = search.starts[0]
    held = alpha_positions(start.size)
    before = float(search.z_cost(start[None])[0])
    z, cost, _ = search.refine(start, 8, held)
    np.testing.assert_array_equal(z[held], start[held])
    assert np.any(z[~held] != start[~held])
    assert cost < before


def test_seed_353_leaves_its_basin_and_reaches_the_noise_on_training(tmp_path):
    result, truth = identified_reference(tmp_path, 353, held_out="covered")
    assert "least squares from every alpha x2, the rest fitted to it first" in result["status"]
    assert "kept)" in result["status"]
    sigma = truth["noise_sigma_deg_s"]
    for name in ("train1", "train2"):
        assert result["rmse_train"][name] / sigma <= 1.1
    # Held out it still misses: the run opens at rest in R+ under a drive
    # between the truth's static level and the fit's, a level no training
    # run breaks away at; now that the training runs are fitted, the
    # verdict says so (stop 54's advice).
    untrained = result["verdict"]["held_out_breakaways_untrained"]
    assert "R+" in [u["regime"] for u in untrained]
