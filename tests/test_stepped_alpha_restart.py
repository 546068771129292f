"""A fit judged at the noise but a few percent above it has each regime's
alpha stepped up and down and the least squares run again from there
(`stepped_alpha`, `fit._stepped_alpha_restarts`; docs/identification.md
"Stop 40").

Reference clean seed 111 shaped the stage and its factor: the least squares
stopped with regimes R- and L+ at 0.77 and 0.71 of the truth's alpha (every
other quantity within 1 %), at 1.22/1.17 noise sigmas on the training runs
where the truth reads 1.01, and 3.3 held out; neither the restart from its
own end nor differential evolution left that valley. The tests below pin
that axis and the stage's rules; they do not validate it (the docs' fresh
seeds do). With the breakaway sub-step's friction at its mean rate (stop
42) the fit stopped with R- alone at 0.77 after L+ was mended by its step,
R- having been stepped first: hence whole passes, repeated after one that
lowered the cost.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from isp_twin.identification import fit
from isp_twin.identification.cost import rmse
from isp_twin.identification.fit import Settings, identify
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.search_space import ALPHA_STEP, stepped_alpha
from isp_twin.model.parameters import RATE_LAYOUT, load_parameters
from isp_twin.reference import design_experiment
from isp_twin.resources import default_parameters_path
from isp_twin.units import DEG

N = RATE_LAYOUT.n_fields


def test_the_step_moves_one_regimes_alpha_by_the_factor_and_nothing_else():
    z = np.arange(4 * N, dtype=float) / 7.0
    stepped = stepped_alpha(z, 2, ALPHA_STEP)
    moved = np.flatnonzero(stepped != z)
    assert moved.tolist() == [2 * N + 4]  # alpha is the fifth search variable
    assert np.exp(stepped[moved[0]] - z[moved[0]]) == pytest.approx(ALPHA_STEP)
    np.testing.assert_allclose(stepped_alpha(stepped, 2, 1.0 / ALPHA_STEP), z)


class _Search(SimpleNamespace):
    """The parts of `fit._Search` the stage reads; `restart` records its
    starts and lowers the cost as the mock of a refinement."""

    def restart(self, start, label):
        self.starts.append((start.copy(), label))
        self.best_cost = self.after.pop(0) if self.after else self.best_cost


def _search(cost, after=(), restart_at_noise=True):
    return _Search(
        s=Settings(restart_at_noise=restart_at_noise),
        free=SimpleNamespace(visited_names=["R+", "R-", "L+", "L-"]),
        noise=1.0,
        target=Settings().converged_ratio,
        best_cost=cost,
        z_best=np.zeros(4 * N),
        starts=[],
        after=list(after),
    )


@pytest.mark.parametrize("cost", [1.0, fit.NEAR_NOISE, Settings().converged_ratio * 1.01])
def test_no_step_at_the_noise_or_where_the_global_search_runs(cost):
    search = _search(cost)
    fit._stepped_alpha_restarts(search)
    assert search.starts == []


def test_no_step_in_fits_that_skip_the_restarts_at_the_noise():
    search = _search(1.1, restart_at_noise=False)
    fit._stepped_alpha_restarts(search)
    assert search.starts == []


def test_a_pass_steps_every_regime_both_ways_and_another_follows_one_that_helped():
    search = _search(1.15)
    fit._stepped_alpha_restarts(search)
    labels = [label for _, label in search.starts]
    assert labels == [
        f"alpha x{f} in {r}" for r in ("R+", "R-", "L+", "L-") for f in ("3", "0.333")
    ]
    # The third restart lowers the cost to the noise: the pass goes on (a
    # regime stepped before another was mended may now find its own
    # valley's exit), and another pass follows, the last (`ALPHA_PASSES`).
    search = _search(1.15, after=[1.12, 1.10, 1.0])
    fit._stepped_alpha_restarts(search)
    assert [label for _, label in search.starts] == labels * fit.ALPHA_PASSES


def _data(exp, name: str) -> MeasuredData:
    r = exp.runs[name]
    return MeasuredData(name, r.t, r.u, r.omega, r.theta, None, r.t[1] - r.t[0])


@pytest.fixture(scope="module")
def clean_111():
    exp = design_experiment(111)
    train = [_data(exp, "train1"), _data(exp, "train2")]
    held = _data(exp, "heldout")
    prior = load_parameters(default_parameters_path()).axis("inner_az")
    result = identify(train, prior, Settings())
    sigma = exp.truth()["noise_sigma_deg_s"] * DEG
    errors = [
        float(rmse(result.rate, [d], timing=result.timing, integration=result.integration)) / sigma
        for d in (*train, held)
    ]
    return result, errors


def test_the_valley_of_seed_111_is_left_by_a_stepped_alpha(clean_111):
    result, _ = clean_111
    assert "least squares from alpha x3 in L+" in result.status


def test_seed_111_reaches_the_benchmark_bound_on_training_and_held_out(clean_111):
    # The bound: 1.3 noise sigmas (the truth's sigma), train and held
    # out; before the stage 1.22 / 1.17 / 3.3.
    _, errors = clean_111
    assert max(errors) <= 1.3
