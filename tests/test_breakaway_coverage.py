"""Breakaways from rest per regime: the training runs' against the held-out
runs' rests (`isp_twin.estimation.coverage.breakaway_counts`, `rest_counts`,
`untrained_breakaways`; docs/identification.md "Stop 54"), and the first
rest against such a regime (`first_untrained_rest`; docs/diagnosis.md
"Stop 60").

The counting is checked on traces built by hand (the regime of each sample
given, so every count is known), the verdicts on them, and `identify` on the
reference clean axis whose miss the advice was written for.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from identified_runs import identified_reference

import isp_twin.commands.diagnose as diagnose_command
from isp_twin.estimation.coverage import (
    MIN_REST_SAMPLES,
    breakaway_counts,
    breakaway_sentence,
    first_untrained_rest,
    rest_counts,
    untrained_breakaways,
)
from isp_twin.estimation.verdict import fit_verdict
from isp_twin.identification.read_out import Timing
from isp_twin.model.parameters import load_parameters
from isp_twin.model.substep_model import DEFAULT_INTEGRATION
from isp_twin.resources import default_parameters_path
from isp_twin.vocabulary import REGIMES

R_PLUS, R_MINUS, L_PLUS, L_MINUS = (REGIMES.index(n) for n in ("R+", "R-", "L+", "L-"))


def _trace(pieces: list[tuple[int, float, int]]) -> tuple[np.ndarray, np.ndarray]:
    """(rate, regime) from (samples, rate, regime index) pieces, in order."""
    rate = np.concatenate([np.full(n, w) for n, w, _ in pieces])
    regime = np.concatenate([np.full(n, r) for n, _, r in pieces])
    return rate, regime


def test_a_rest_then_motion_is_one_breakaway_in_the_regime_it_moves_into():
    rate, regime = _trace(
        [(5, 0.0, R_MINUS), (10, -0.1, R_MINUS), (3, 0.0, L_PLUS), (4, 0.2, L_PLUS)]
    )
    counts = breakaway_counts([rate], [regime])
    assert counts.tolist() == [0, 1, 1, 0]


def test_a_rest_shorter_than_the_minimum_and_a_rest_that_ends_the_run_do_not_count():
    short = MIN_REST_SAMPLES - 1
    rate, regime = _trace(
        [(short, 0.0, R_PLUS), (6, 0.3, R_PLUS), (8, 0.0, L_MINUS)]  # opens, ends at rest
    )
    assert breakaway_counts([rate], [regime]).sum() == 0
    # both rests that last long enough push against their regimes
    assert rest_counts([rate], [regime]).tolist() == [0, 0, 0, 1]


def test_a_rest_the_drive_turns_within_counts_against_both_regimes_once():
    rate, regime = _trace(
        [(4, 0.1, R_PLUS), (3, 0.0, R_PLUS), (5, 0.0, R_MINUS), (4, -0.1, R_MINUS)]
    )
    assert rest_counts([rate], [regime]).tolist() == [1, 1, 0, 0]
    assert breakaway_counts([rate], [regime]).tolist() == [0, 1, 0, 0]


def test_runs_are_counted_apart_and_summed():
    a = _trace([(3, 0.0, L_MINUS), (2, -0.1, L_MINUS)])
    b = _trace([(2, 0.1, L_MINUS), (3, 0.0, L_MINUS), (2, -0.1, L_MINUS)])
    counts = breakaway_counts([a[0], b[0]], [a[1], b[1]])
    assert counts.tolist() == [0, 0, 0, 2]


@pytest.mark.parametrize(
    "trained, rests, named",
    [
        ([0, 3, 3, 0], [2, 1, 0, 4], ["R+", "L-"]),
        ([1, 1, 1, 1], [5, 5, 5, 5], []),
        ([0, 0, 0, 0], [0, 0, 0, 0], []),
    ],
)
def test_untrained_are_the_rested_regimes_the_training_never_breaks_away_in(trained, rests, named):
    found = untrained_breakaways(np.array(trained), np.array(rests))
    assert [b.regime for b in found] == named
    assert [b.held_out for b in found] == [rests[REGIMES.index(n)] for n in named]


def test_the_verdict_says_it_only_beside_an_error_above_the_noise():
    floors = {"t": 1.0, "h": 1.0}
    counts = (np.array([0, 3, 3, 0]), np.array([2, 0, 0, 0]))
    off = fit_verdict({"t": 1.0, "h": 4.0}, floors, ["h"], "Try more.", breakaways=counts)
    assert off.advice.startswith(breakaway_sentence(off.untrained))
    assert "regime(s) R+ (2 rests)" in off.advice
    assert off.to_json()["held_out_breakaways_untrained"] == [
        {"regime": "R+", "training_breakaways": 0, "held_out_rests": 2}
    ]
    assert off.to_json()["breakaways"]["training_breakaways"]["R-"] == 3
    on = fit_verdict({"t": 1.0, "h": 1.0}, floors, ["h"], "Try more.", breakaways=counts)
    assert on.advice == ""
    assert on.to_json()["held_out_breakaways_untrained"][0]["regime"] == "R+"
    # a model that misses the training runs too: the static level is not the story
    untrained_off = fit_verdict({"t": 2.0, "h": 4.0}, floors, ["h"], "Try more.", breakaways=counts)
    assert untrained_off.advice == "Try more."
    assert untrained_off.to_json()["held_out_breakaways_untrained"][0]["regime"] == "R+"


def test_the_first_rest_against_an_untrained_regime_is_found():
    rate, regime = _trace(
        [(10, 0.1, R_PLUS), (5, 0.0, R_MINUS), (10, -0.1, R_MINUS), (4, 0.0, L_MINUS), (7, 0.1, 0)]
    )
    assert first_untrained_rest(rate, regime, [L_MINUS]) == 25
    assert first_untrained_rest(rate, regime, [R_MINUS, L_MINUS]) == 10
    assert first_untrained_rest(rate, regime, [L_PLUS]) == rate.size


def test_a_rest_counts_if_the_drive_pushes_that_way_at_any_of_its_samples():
    rate, regime = _trace(
        [(3, 0.1, R_PLUS), (2, 0.0, R_PLUS), (3, 0.0, L_MINUS), (3, -0.1, L_MINUS)]
    )
    assert first_untrained_rest(rate, regime, [L_MINUS]) == 3


def test_a_zero_shorter_than_a_rest_is_a_reversal_not_a_rest():
    short = MIN_REST_SAMPLES - 1
    rate, regime = _trace([(5, 0.1, L_MINUS), (short, 0.0, L_MINUS), (5, -0.1, L_MINUS)])
    assert first_untrained_rest(rate, regime, [L_MINUS]) == rate.size


@pytest.mark.parametrize("train_floors, said", [(1.0, True), (2.0, False)])
def test_diagnose_says_it_where_the_final_model_fits_the_training_runs(
    monkeypatch, train_floors, said
):
    counts = (np.array([0, 3, 3, 0]), np.array([0, 1, 1, 2]))
    monkeypatch.setattr(diagnose_command, "model_breakaways", lambda rate, runs, *a, **k: counts)
    params = load_parameters(default_parameters_path())
    diag = SimpleNamespace(
        params_out=params,
        timing=Timing(),
        integration=DEFAULT_INTEGRATION,
        stack=SimpleNamespace(flat=np.ravel),
        residual_after=(np.full(100, train_floors * 1e-3),),
        noise_floor=1e-3,
    )
    result = {"converged": False, "verdict": "held-out RMS error 4.00 x the noise floor"}
    diagnose_command._with_breakaways(result, diag, next(iter(params.axes)), "measured", [], [])
    assert [b["regime"] for b in result["held_out_breakaways_untrained"]] == ["L-"]
    assert result["breakaways"]["held_out_rests"]["L-"] == 2
    assert ("rest against regime(s) L- (2 rests)" in result["verdict"]) is said


def test_identify_names_the_regime_whose_breakaway_the_training_runs_do_not_measure(tmp_path):
    """Reference clean seed 348 (the benchmark's held-out design): `identify`
    fits the training runs at the noise with L-'s static level 9 % above
    the truth's, and a held-out step pushes the axis at rest in L- with a
    drive between the two; the cosines never break away in L-."""
    result, truth = identified_reference(tmp_path, 348, held_out="covered")
    verdict = result["verdict"]
    sigma = truth["noise_sigma_deg_s"]
    assert result["rmse_validation"]["heldout"] / sigma > 5  # the miss the advice explains
    assert verdict["breakaways"]["training_breakaways"]["L-"] == 0
    assert verdict["breakaways"]["held_out_rests"]["L-"] >= 1
    named = [b["regime"] for b in verdict["held_out_breakaways_untrained"]]
    assert "L-" in named
    assert "rest against regime(s)" in verdict["advice"]
