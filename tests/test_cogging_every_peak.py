"""Every peak of cogging's periodogram is refined, not only the one a
simulation at the current rates ranks best (`Effect.every_guess_refined`,
`candidates._guessed_starts`).

A regression test on the axis that shaped it, not its validation
(docs/diagnosis.md "Stop 46"): reference cogging axis 308 (a 0.55 s axis),
with the rates `isp-twin identify` found there at stop 45, 32 noise floors
from the training runs. The periodogram's three peaks hold the truth's
period (115 per turn), but at that base a simulation ranked a 211-per-turn
peak first; the fit from it ended at a period of 0.0304 rad, and diagnose
answered none at 91 noise floors held out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from isp_twin.diagnosis.candidates import _guessed_starts, fit_candidates
from isp_twin.diagnosis.prepared_runs import checked_inputs
from isp_twin.diagnosis.residual import residual_context
from isp_twin.diagnosis.search import _prepared
from isp_twin.identification.measured import MeasuredData
from isp_twin.model.effects import effect_class
from isp_twin.model.parameters import load_parameters
from isp_twin.model.substep_model import DEFAULT_INTEGRATION
from isp_twin.reference import design_experiment

IDENTIFIED = Path(__file__).parent / "data" / "reference_cogging_308_identified.yaml"


@pytest.fixture(scope="module")
def case():
    exp = design_experiment(308, "cogging")
    runs = [
        MeasuredData(n, r.t, r.u, r.omega, r.theta, None, 1e-3)
        for n, r in exp.runs.items()
        if n in ("train1", "train2")
    ]
    params = load_parameters(IDENTIFIED)
    checked = checked_inputs(runs, (), params, "inner_az", ("cogging",), "measured")
    data, x_start, _ = _prepared(checked, "measured", 0, DEFAULT_INTEGRATION, None, False, 8, 2)
    return exp.truth()["effects"][0]["params"], data.train, x_start


def test_every_periodogram_peak_is_a_start_at_the_current_rates(case):
    _, train, x = case
    context = residual_context(train, x)
    classes = {"cogging": effect_class("cogging", "candidate effect")}
    starts, rate_starts = _guessed_starts(train, x, classes, ["cogging"], (), context)
    peaks = classes["cogging"].guesses(context)
    assert len(peaks) == 3
    assert sorted(s["period_rad"] for s in starts["cogging"]) == sorted(
        float(np.clip(p["period_rad"], *classes["cogging"].bounds["period_rad"])) for p in peaks
    )
    assert np.array_equal(rate_starts["cogging"], np.tile(x, (3, 1)))


def test_the_fit_ends_at_the_truths_period(case):
    true, train, x = case
    fit = fit_candidates(train, x, ["cogging"], max_iter=8)["cogging"]
    assert fit.params["period_rad"] == pytest.approx(true["period_rad"], rel=0.01)
    assert fit.params["amplitude_rad_s2"] == pytest.approx(true["amplitude_rad_s2"], rel=0.1)
