"""The held-out error before the model first rests against a regime the
training runs never break away in (`isp_twin.estimation.coverage.first_untrained_rest`,
`isp_twin.identification.cost.held_out_determined`, the verdicts' JSON
``held_out_before_untrained_rest``; docs/diagnosis.md "Stop 60").

The error on a reference run against the Eq. 9 residuals it must equal,
and the verdict's JSON and sentence on given figures (the rest itself on
traces built by hand: tests/test_breakaway_coverage.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from truth_error import measured_runs, truth_parameter_set

from isp_twin.estimation.coverage import (
    DeterminedPart,
    RegimeBreakaways,
    breakaway_sentence,
    first_untrained_rest,
)
from isp_twin.estimation.verdict import fit_verdict
from isp_twin.identification.cost import held_out_determined, residuals, simulate_data
from isp_twin.identification.read_out import Timing
from isp_twin.reference import design_experiment
from isp_twin.vocabulary import REGIMES


@pytest.fixture(scope="module")
def reference_run():
    """Reference clean axis 348's held-out run (random steps, rests), with
    the truth's rate form recorded at the reference's read-out."""
    exp = design_experiment(348, None, held_out="covered")
    truth = exp.truth()
    timing = Timing(0.0, truth["sensors"]["gyro_averaged"])
    params = truth_parameter_set(truth, "inner_az", timing)
    return measured_runs(exp)["heldout"], params.axis("inner_az").rate_params(), timing


def test_no_untrained_regime_no_part(reference_run):
    held, rate, timing = reference_run
    assert held_out_determined(rate, [held], (), timing=timing) == ()


def test_the_part_is_the_eq9_error_over_the_samples_before_the_first_rest(reference_run):
    """With every regime untrained the part ends at the model's first rest;
    its error is Eq. 9's residual over samples 1..first-1 (the same
    simulation as the whole run's error)."""
    held, rate, timing = reference_run
    every = [RegimeBreakaways(name, 1) for name in REGIMES]
    (part,) = held_out_determined(rate, [held], every, timing=timing)
    sim = simulate_data(rate, held, timing=timing)
    own = sim.omega_true  # the axis's own rate: the averaged reading is not 0 at a rest's start
    assert part.run == "heldout" and part.of_samples == held.omega.size
    assert part.samples == first_untrained_rest(own, sim.regime, range(len(REGIMES)))
    assert 1 < part.samples < part.of_samples  # the run rests
    e = residuals(rate, [held], timing=timing)
    assert part.rmse == pytest.approx(np.sqrt(np.mean(e[: part.samples - 1] ** 2)), rel=1e-12)


def test_the_verdict_states_the_part_beside_the_untrained_regime():
    counts = (np.array([0, 3, 3, 0]), np.array([0, 1, 1, 2]))
    floors = {"t": 1e-3, "h": 2e-3}
    part = DeterminedPart("h", 1689, 6000, 2.2e-3)
    args = ({"t": 1e-3, "h": 8e-3}, floors, ["h"], "Try more.")
    off = fit_verdict(*args, breakaways=counts, determined=[part])
    said = "Before its first such rest (sample 1689 of 6000) h reads 1.10 x the noise floor."
    assert off.advice.startswith(breakaway_sentence(off.untrained) + said)
    (got,) = off.to_json()["held_out_before_untrained_rest"]
    assert got["samples"] == 1689 and got["of_samples"] == 6000
    assert got["rmse_over_noise_floor"] == pytest.approx(1.1)
    assert got["rmse_deg_s"] == pytest.approx(math.degrees(2.2e-3))
    # Not said where the training runs are not fitted; still in the JSON.
    untrained_off = fit_verdict(
        {"t": 2e-3, "h": 8e-3}, floors, ["h"], "Try more.", breakaways=counts, determined=[part]
    )
    assert untrained_off.advice == "Try more."
    assert untrained_off.to_json()["held_out_before_untrained_rest"][0]["samples"] == 1689


def test_a_part_without_samples_has_no_figure():
    part = DeterminedPart("h", 1, 6000, float("nan"))
    assert part.sentence(1e-3) == ""
    counts = (np.array([0, 3, 3, 0]), np.array([0, 1, 1, 2]))
    verdict = fit_verdict(
        {"t": 1e-3, "h": 8e-3},
        {"t": 1e-3, "h": 1e-3},
        ["h"],
        "Try more.",
        breakaways=counts,
        determined=[part],
    )
    assert verdict.to_json()["held_out_before_untrained_rest"][0]["rmse_over_noise_floor"] is None
