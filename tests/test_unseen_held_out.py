"""An effect the held-out runs never reach is judged on the training runs
(`rounds._effect_itself`, `_unseen_held_out`, `_training_needs_it`).

`_effect_itself` overrules a significant candidate whose own rate parameters
do as well held out with the effect switched off. Where the held-out runs
never reach the effect (a saturation limit above every held-out command),
the two predictions are the same sample for sample and that test has no
power: it overruled every such effect. The shaping cell, benchmark
saturation seed 323 (covered design, stop 48): the limit within 1.1 % of the
truth's, reached by a quarter of one training run and by no held-out
command, 2.4 noise floors held out against the base's 26, answered `none`
(docs/diagnosis.md "Stop 48"). There the base refitted from the candidate's
rate parameters decides: the effect stands where it fits the training runs
better than that refit (by `MIN_GAIN` of the error and in BIC).

Stand-ins for the fits; the held-out comparison itself is real.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from round_state_double import RoundStateDouble, fit_double

from isp_twin.diagnosis import rounds
from isp_twin.diagnosis.selection import MIN_GAIN, Verdict

FLOOR = 5e-4  # rad/s
RNG = np.random.default_rng(3)
OWN = [2.4 * FLOOR * RNG.standard_normal(3000)]  # the candidate's held-out residuals


def _data(held_off):
    """Held-out residuals of the switched-off fit as given."""
    return SimpleNamespace(held_residuals=lambda fits: [held_off], train=None, max_iter=8)


@pytest.fixture
def base_refit(monkeypatch):
    """The base refitted from the candidate's rates: training sse and BIC as set."""
    calls = []
    result = {"sse": 1.0, "bic": 0.0}

    def refit(stack, rate_vector, name, fixed=(), max_iter=8):
        calls.append(name)
        return fit_double(name, sse=result["sse"], bic=result["bic"])

    monkeypatch.setattr(rounds, "fit_candidate", refit, raising=False)
    monkeypatch.setattr(rounds, "_not_the_effect", lambda data, st, name: "")
    # The switched-off fit: the limit at its null (infinity); predicted by `_data`.
    monkeypatch.setattr(
        rounds, "_switched_off", lambda fit: SimpleNamespace(params={"limit_digits": np.inf})
    )
    return SimpleNamespace(calls=calls, result=result)


def _judged(held_off, sse=0.2, bic=-25865.0):
    fit = fit_double("saturation", {"limit_digits": 717.6}, sse=sse, bic=bic)
    fit.rate_vector, fit.fixed = np.zeros(24), ()
    st = RoundStateDouble({"saturation": fit}, {"saturation": OWN}, floor=FLOOR)
    v = Verdict("saturation", 2.4 * FLOOR, 30.3, bic, True, "held-out MSE lower")
    return rounds._effect_itself(_data(held_off), st, [v])[0]


def test_an_effect_the_training_runs_need_stands(base_refit):
    out = _judged([OWN[0].copy()])
    assert out.significant
    assert base_refit.calls == [rounds.BASELINE]


def test_an_effect_the_base_refit_does_as_well_without_is_overruled(base_refit):
    base_refit.result.update(sse=0.2 / (1.0 - 0.5 * MIN_GAIN), bic=-25860.0)
    out = _judged([OWN[0].copy()])
    assert not out.significant
    assert "never reach" in out.reason


def test_a_lower_error_with_a_higher_bic_is_overruled(base_refit):
    base_refit.result.update(bic=-30000.0)
    assert not _judged([OWN[0].copy()]).significant


def test_where_the_held_out_runs_reach_it_the_held_out_rule_decides(base_refit):
    # The switched-off fit as good held out (same error, other samples): overruled
    # by the held-out rule, and the training runs are not asked.
    off = [2.4 * FLOOR * RNG.standard_normal(3000)]
    out = _judged(off)
    assert not out.significant
    assert "switched off" in out.reason
    assert base_refit.calls == []


def test_an_effect_at_its_null_values_is_left_to_the_held_out_rule(base_refit, monkeypatch):
    # A saturation limit at infinity is the model without it (as a delay of 0,
    # tests/test_effect_itself.py): the same predictions, and no evidence.
    monkeypatch.setattr(rounds, "_switched_off", lambda fit: fit)
    out = _judged([OWN[0].copy()])
    assert not out.significant
    assert "switched off" in out.reason
    assert base_refit.calls == []


def test_unseen_means_equal_to_a_millionth_of_the_floor():
    a = OWN[0]
    assert rounds._unseen_held_out([a + 0.5e-6 * FLOOR], [a], FLOOR)
    assert not rounds._unseen_held_out([a + 2e-6 * FLOOR], [a], FLOOR)
