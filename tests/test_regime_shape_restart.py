"""Restarts from the other regimes' friction shape (`shape_outliers`,
`consensus_start`) and with the Stribeck curve opened (`linear_stribeck`,
`opened_stribeck`); docs/identification.md "Stop 39".

Reference clean seed 107 is the axis that shaped the first stage: the least
squares settled regime L- on a nearly linear Stribeck curve (alpha 300x
below the other regimes') at 1.07/1.01 noise floors on the training runs,
and its breakaway, which no training run tests, at 45 % of the truth: 10.5
floors held out. Clean seed 126 shaped the second: all four regimes ended
with Ts = Tc and a Stribeck curve that is a straight line over the runs'
speeds, 5.9 floors held out. The tests below pin those axes; they do not
validate the stages (the benchmark in the docs does, on other seeds). Seed
126 is pinned with the least squares' columns at the model's own sub-steps:
with identify's default 4-sub-step columns (docs/identification.md "Stop
83") the least squares from the data's start opens the curve itself.
"""

from __future__ import annotations

import numpy as np
import pytest
from identified_runs import identified_reference

from isp_twin.identification.search_space import (
    LINEAR_STRIBECK,
    OPENED_ALPHA_SPEED,
    PRIOR_FIELDS,
    consensus_start,
    linear_stribeck,
    opened_stribeck,
    shape_outliers,
)
from isp_twin.model.parameters import RATE_LAYOUT
from isp_twin.units import DEG

N = RATE_LAYOUT.n_fields


def _table(shapes):
    """Search variables of len(shapes) regimes: pole, gain fixed, the
    friction fields (`PRIOR_FIELDS`) from `shapes` (natural values)."""
    t = np.zeros((len(shapes), N))
    t[:, 0], t[:, 1] = np.log(0.02), np.log(1e-4)
    t[:, list(PRIOR_FIELDS)] = np.log(np.asarray(shapes, float))
    return t


def test_regimes_within_the_spread_get_no_restart():
    t = _table([[1.0, 1.0, 1.0], [2.0, 0.6, 1.5], [0.5, 1.4, 2.5], [1.2, 2.0, 0.6]])
    assert shape_outliers(t.ravel(), 3.0) == []


def test_levels_apart_alone_make_no_outlier():
    # A torque offset splits the Coulomb levels of the two directions; a
    # Ts/Tc near 1 makes b·(Ts-Tc) differ by decades: alpha alone decides.
    t = _table([[0.2, 1e-3, 1.0], [5.0, 1.0, 1.1], [0.2, 1.0, 0.9], [5.0, 1e-3, 1.0]])
    assert shape_outliers(t.ravel(), 3.0) == []


def test_a_far_alpha_makes_its_regime_an_outlier_and_only_it():
    # The median of the others: the outlier does not drag the other regimes
    # outside the spread, as the others' mean would (log mean of alpha with
    # a 1e-3 outlier: a factor 5.6 below the rest).
    t = _table([[1.0, 1.0, 1.0], [1.1, 0.9, 1.2], [0.9, 1.1, 0.8], [1.0, 1.0, 1e-3]])
    assert shape_outliers(t.ravel(), 3.0) == [3]
    assert shape_outliers(t.ravel(), 2000.0) == []


def test_the_restart_takes_the_others_median_and_keeps_the_rest():
    t = _table([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0], [1e-3, 1e3, 1e-3]])
    start = consensus_start(t.ravel(), 3).reshape(-1, N)
    np.testing.assert_allclose(np.exp(start[3, list(PRIOR_FIELDS)]), [4.0, 5.0, 6.0])
    np.testing.assert_array_equal(start[:3], t[:3])
    np.testing.assert_array_equal(start[3, :2], t[3, :2])


def test_two_regimes_restart_from_each_other():
    t = _table([[1.0, 1.0, 1.0], [1.0, 1.0, 10.0]])
    assert shape_outliers(t.ravel(), 3.0) == [0, 1]
    np.testing.assert_allclose(consensus_start(t.ravel(), 0), t[[1, 1]].ravel())


def test_no_spread_or_one_regime_gets_no_restart():
    far = _table([[1.0, 1.0, 1.0], [1.0, 1.0, 1e-4]]).ravel()
    assert shape_outliers(far, None) == []
    assert shape_outliers(far[:N], 3.0) == []


def test_a_regime_whose_curve_is_a_line_over_the_runs_speeds_is_opened():
    speed = 0.2  # rad/s
    alphas = np.array([0.5, 0.9, 1.1, 50.0]) * LINEAR_STRIBECK / speed
    t = _table([[1.0, 1e-6, a] for a in alphas])
    assert linear_stribeck(t.ravel(), speed) == [0, 1]
    opened = opened_stribeck(t.ravel(), [0, 1], speed).reshape(-1, N)
    # Ts/Tc = 2 (the gap equals b·Tc), alpha·|w|rms = OPENED_ALPHA_SPEED
    np.testing.assert_allclose(opened[:2, 3], opened[:2, 2])
    np.testing.assert_allclose(np.exp(opened[:2, 4]) * speed, OPENED_ALPHA_SPEED)
    np.testing.assert_array_equal(opened[2:], t[2:])
    np.testing.assert_array_equal(opened[:, :3], t[:, :3])


def _identified(tmp_path_factory, seed, options: tuple[str, ...] = ()):
    """`identify` with defaults (and `options`) on reference clean seed
    `seed`, judged held out."""
    return identified_reference(tmp_path_factory.mktemp(f"clean{seed}"), seed, options=options)


def _assert_converged_held_out(result):
    """Every run, the held-out one among them, within the verdict's 1.5 noise floors."""
    per_set = result["verdict"]["per_set"]
    assert per_set["heldout"]["role"] == "held_out"
    assert all(s["rmse_over_noise_floor"] <= 1.5 for s in per_set.values())


@pytest.fixture(scope="module")
def clean_107(tmp_path_factory):
    return _identified(tmp_path_factory, 107)


@pytest.fixture(scope="module", params=["own", "default"])
def clean_126(tmp_path_factory, request):
    options = ("--jacobian-substeps", "0") if request.param == "own" else ()
    return _identified(tmp_path_factory, 126, options) + (request.param,)


def test_a_closed_stribeck_curve_on_every_regime_is_opened_to_the_noise(clean_126):
    result, truth, columns = clean_126
    if columns == "own":  # the stage opens it
        assert "Stribeck curve opened in R+, R-, L+, L-" in result["status"]
    per_set = result["verdict"]["per_set"]
    assert per_set["train1"]["rmse_over_noise_floor"] <= 1.5
    assert per_set["train2"]["rmse_over_noise_floor"] <= 1.5
    # The training runs leave this axis' held-out run open (the verdict's
    # spread, `held_out_spread`, straddles 1.5 floors: 1.15-6.0 at stop 40's
    # fit, which read 1.33; 1.23-7.3 at stop 41's, which reads 1.82 with a
    # lower training cost): which end a fit lands at is not pinned.
    spread = result["verdict"]["held_out_spread"][0]
    assert spread["rmse_over_noise_floor_p05"] <= 1.5 < spread["rmse_over_noise_floor_p95"]
    # Ts/Tc of the truth is 2.3-2.5 in every regime; before the stage 1.00.
    for name, p in result["parameters"].items():
        true = truth["rate_form"]["regimes"][name]
        assert p["Ts"] / p["Tc"] == pytest.approx(true["static"] / true["coulomb"], rel=0.25)


def test_a_regime_left_on_a_linear_stribeck_curve_is_restarted_to_the_noise(clean_107):
    result, _ = clean_107
    assert "friction shape in L-" in result["status"]
    _assert_converged_held_out(result)


def test_the_untested_breakaway_comes_from_the_restart_near_the_truth(clean_107):
    # L-'s breakaway b·Ts [deg/s per sample] within 10 % of the truth's;
    # before the stage it was 45 % of it.
    result, truth = clean_107
    p = result["parameters"]["L-"]
    true_static = truth["rate_form"]["regimes"]["L-"]["static"] / DEG
    assert p["b"] * p["Ts"] == pytest.approx(true_static, rel=0.10)
