"""The fit verdict: noise floor estimate, the converged rule, valid JSON."""

import json
import math

import numpy as np
import pytest

from isp_twin.estimation.verdict import CONVERGED_RATIO, fit_verdict, noise_floor_of
from isp_twin.units import DEG


@pytest.mark.parametrize("sigma", [0.01 * DEG, 0.1 * DEG])
def test_noise_floor_recovers_white_noise_under_a_smooth_response_with_steps(sigma):
    rng = np.random.default_rng(3)
    t = np.arange(6000) * 1e-3
    # A slow response with a few breakaway corners: what an axis's rate looks like.
    smooth = 0.5 * np.sin(2 * np.pi * 0.5 * t) + 0.2 * (np.sin(2 * np.pi * 2 * t) > 0.5)
    runs = [smooth + rng.normal(0, sigma, t.size) for _ in range(2)]
    assert noise_floor_of(runs) == pytest.approx(sigma, rel=0.05)


def test_converged_only_when_every_set_is_within_the_limit():
    floors = {"a": 1.0, "b": 1.0, "c": 2.0}
    ok = fit_verdict({"a": 1.1, "b": CONVERGED_RATIO, "c": 2.5}, floors, ["c"], "try x")
    assert ok.converged and ok.advice == ""
    bad = fit_verdict({"a": 1.1, "b": 1.0, "c": 3.1}, floors, ["c"], "try x")
    assert not bad.converged
    assert bad.worst_ratio == pytest.approx(1.55)
    assert bad.advice == "try x"
    assert any("NOT CONVERGED" in line for line in bad.lines())


def test_verdict_json_is_strict_json_with_units_and_null_for_undefined():
    v = fit_verdict({"a": 0.01, "b": 0.02}, {"a": 0.01, "b": math.nan}, ["b"], "advice")
    text = json.dumps(v.to_json(), allow_nan=False)
    back = json.loads(text)
    assert back["converged"] is False
    assert back["per_set"]["b"]["noise_floor_deg_s"] is None
    assert back["per_set"]["a"]["rmse_over_noise_floor"] == pytest.approx(1.0)
    assert back["per_set"]["a"]["rmse_deg_s"] == pytest.approx(0.01 / DEG)


@pytest.mark.parametrize("seed", range(6))
def test_noise_floor_is_not_raised_by_a_payloads_ringing(seed):
    # A payload ringing at 19 Hz, 300 noise sigmas high, on a slow response
    # (reference resonance seed 57 rang at 19 Hz on every held-out sample).
    sigma = 0.02 * DEG
    rng = np.random.default_rng(seed)
    t = np.arange(6000) * 1e-3
    ringing = 300 * sigma * np.sin(2 * np.pi * 19.0 * t + rng.uniform(0, 2 * np.pi))
    smooth = 0.5 * np.sin(2 * np.pi * 0.5 * t)
    runs = [smooth + ringing + rng.normal(0, sigma, t.size)]
    assert noise_floor_of(runs) == pytest.approx(sigma, rel=0.05)
