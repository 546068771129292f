"""Regimes the training runs move in for a small share of their samples
(`isp_twin.estimation.coverage.thin_training`, docs/diagnosis.md "Stop 45").

Runs built by hand: the angle's sign and the rate's sign put each sample in
a regime, so the shares are known exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.commands.diagnose import _with_coverage
from isp_twin.estimation.coverage import (
    MIN_REACH_FLOORS,
    THIN_RATIO,
    thin_sentence,
    thin_training,
)
from isp_twin.estimation.verdict import fit_verdict
from isp_twin.identification.measured import MeasuredData

DT = 1e-3
FLOOR = 1e-4  # rad/s
FAST = 100 * FLOOR  # well above MIN_REACH_FLOORS floors


def _run(name: str, counts: dict[str, int], rest: int = 0) -> MeasuredData:
    """`counts[regime]` samples moving at FAST in each regime, then `rest`
    samples at rest (rate 0), in that order."""
    sign = {"R+": (1, 1), "R-": (1, -1), "L+": (-1, 1), "L-": (-1, -1)}
    angle, omega = [], []
    for regime, n in counts.items():
        side, direction = sign[regime]
        angle += [0.1 * side] * n
        omega += [FAST * direction] * n
    angle += [0.1] * rest
    omega += [0.0] * rest
    n = len(omega)
    t = np.arange(n) * DT
    return MeasuredData(name, t, np.zeros(n), np.array(omega), np.array(angle), None, DT)


def test_the_regime_the_held_out_run_moves_in_six_times_as_often_is_named():
    # Sensor bias 305's shares: L- 5.7 % of the training samples, 36-37 % held out.
    train = [_run("t1", {"R+": 2000, "R-": 2000, "L-": 342}, rest=1658)]
    held = [_run("h", {"R+": 1000, "R-": 1000, "L-": 2220}, rest=1780)]
    out = thin_training(train, held, FLOOR)
    assert [t.regime for t in out] == ["L-"]
    assert out[0].training_share == pytest.approx(342 / 6000)
    assert out[0].held_out_share == pytest.approx(2220 / 6000)
    said = thin_sentence(out)
    assert "L- (37 % of the samples held out, 5.7 % in training)" in said


def test_shares_within_the_ratio_name_nothing():
    train = [_run("t1", {"R+": 1000, "L-": 1000}, rest=1000)]
    at_limit = int(THIN_RATIO * 1000) - 10  # just under the ratio, same length
    held = [_run("h", {"L-": at_limit}, rest=3000 - at_limit)]
    assert thin_training(train, held, FLOOR) == ()
    assert thin_sentence(()) == ""


def test_a_regime_never_moved_in_during_training_is_named():
    train = [_run("t1", {"R+": 3000})]
    held = [_run("h", {"R+": 1500, "L+": 1500})]
    assert [t.regime for t in thin_training(train, held, FLOOR)] == ["L+"]


def test_slow_samples_and_a_few_held_out_ones_do_not_count():
    train = [_run("t1", {"R+": 3000})]
    held = [_run("h", {"R+": 2960, "L+": 40})]  # 40 < MIN_SAMPLES
    assert thin_training(train, held, FLOOR) == ()
    # At a floor above FAST / MIN_REACH_FLOORS no sample is moving.
    held = [_run("h", {"R+": 1500, "L+": 1500})]
    assert thin_training(train, held, 1.01 * FAST / MIN_REACH_FLOORS) == ()
    assert thin_training(train, [], FLOOR) == ()


def test_identify_and_diagnose_state_it_only_beside_an_error_above_the_noise():
    train = [_run("t1", {"R+": 3000})]
    held = [_run("h", {"R+": 1500, "L+": 1500})]
    thin = thin_training(train, held, FLOOR)
    floors = {"t1": FLOOR, "h": FLOOR}
    off = fit_verdict({"t1": FLOOR, "h": 5 * FLOOR}, floors, ["h"], "Try more.", thin=thin)
    assert off.advice.startswith("The held-out runs move in regime(s) L+")
    assert off.to_json()["held_out_thin_in_training"][0]["regime"] == "L+"
    on = fit_verdict({"t1": FLOOR, "h": FLOOR}, floors, ["h"], "Try more.", thin=thin)
    assert on.advice == ""
    result = {"converged": False, "verdict": "held-out RMS error 3.00 x the noise floor"}
    _with_coverage(result, train, held, FLOOR)
    assert (
        "move in regime(s) L+ (50 % of the samples held out, 0.0 % in training)"
        in (result["verdict"])
    )
    assert result["held_out_thin_in_training"][0]["held_out_share_moving"] == 0.5
    result = {"converged": True, "verdict": "at the noise"}
    _with_coverage(result, train, held, FLOOR)
    assert result["verdict"] == "at the noise"
