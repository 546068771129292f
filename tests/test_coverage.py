"""The held-out runs against the training runs' speeds, per regime
(`isp_twin.estimation.coverage`), and what the verdicts of `identify` and
`diagnose` say of it (docs/identification.md "Stop 37")."""

from __future__ import annotations

import json

import numpy as np
import pytest

from isp_twin.cli import main
from isp_twin.commands.diagnose import _with_coverage
from isp_twin.estimation.coverage import BEYOND_RATIO, REACH_QUANTILE, beyond_training
from isp_twin.estimation.verdict import fit_verdict
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.side_angle import sides_as_read
from isp_twin.units import DEG
from isp_twin.vocabulary import REGIMES

DT = 1e-3


def _run(name: str, speed: float, n: int = 4000, seed: int = 0) -> MeasuredData:
    """A run that sweeps both sides in both directions: angle sin, rate
    speed * cos (rad/s), plus a little noise."""
    t = np.arange(n) * DT
    rng = np.random.default_rng(seed)
    omega = speed * np.cos(2 * np.pi * t) + 1e-4 * rng.standard_normal(n)
    angle = 0.1 * np.sin(2 * np.pi * t)
    return MeasuredData(name, t, np.zeros(n), omega, angle, None, DT)


def test_a_held_out_run_like_the_training_runs_is_within_them():
    train = [_run("a", 1.0, seed=1), _run("b", 1.0, seed=2)]
    assert beyond_training(train, [_run("h", 1.0, seed=3)], 1e-4) == ()


def test_a_faster_held_out_run_is_beyond_in_every_regime_by_its_speed_ratio():
    train = [_run("a", 1.0, seed=1)]
    held = [_run("h", 2.0, seed=1)]
    out = beyond_training(train, held, 1e-4)
    assert [b.regime for b in out] == list(REGIMES)
    for b in out:
        # The reach is a quantile of |rate|: scaling the rate scales it
        # (up to the noise, the same draw in both runs).
        assert b.held_out_rad_s / b.training_rad_s == pytest.approx(2.0, rel=1e-3)
        assert b.training_rad_s == pytest.approx(np.sin(np.pi / 2 * REACH_QUANTILE), rel=0.01)


def test_only_the_regime_the_training_runs_do_not_reach_is_named():
    train = [_run("a", 1.0, seed=1)]
    held = _run("h", 1.0, seed=1)
    fast = held.omega.copy()
    right_neg = (held.angle > 0) & (fast < 0)
    fast[right_neg] *= 3.0  # only R- is driven faster
    out = beyond_training(
        train, [MeasuredData("h", held.t, held.u, fast, held.angle, None, DT)], 1e-4
    )
    assert [b.regime for b in out] == ["R-"]


def test_a_speed_ratio_at_the_limit_is_not_beyond():
    train = [_run("a", 1.0, seed=1)]
    assert beyond_training(train, [_run("h", 0.99 * BEYOND_RATIO, seed=1)], 1e-4) == ()


def test_speeds_within_the_noise_and_regimes_barely_visited_are_not_named():
    train = [_run("a", 1e-4, seed=1)]
    # The held-out run reaches 2e-3 rad/s, far beyond the training runs'
    # noise-sized speeds: 20 floors of 1e-4 rad/s (named), 2 of 1e-3 (not).
    held = [_run("h", 2e-3, seed=2)]
    assert beyond_training(train, held, 1e-4) != ()
    assert beyond_training(train, held, 1e-3) == ()
    short = [_run("h", 3.0, n=40, seed=2)]  # 40 samples in all
    assert beyond_training(train, short, 1e-4) == ()
    assert beyond_training(train, [], 1e-4) == ()


def test_the_verdict_opens_its_advice_with_the_regimes_beyond_and_lists_them():
    beyond = beyond_training([_run("a", 1.0, seed=1)], [_run("h", 2.0, seed=1)], 1e-4)
    rmse = {"a": 1e-4, "h": 5e-4}
    floors = {"a": 1e-4, "h": 1e-4}
    off = fit_verdict(rmse, floors, ["h"], "Try more.", beyond)
    assert not off.converged
    assert off.advice.startswith("The held-out runs go faster than the training runs")
    assert off.advice.endswith("Try more.")
    listed = off.to_json()["held_out_beyond_training"]
    assert [b["regime"] for b in listed] == list(REGIMES)
    assert listed[0]["held_out_reach_deg_s"] == pytest.approx(beyond[0].held_out_rad_s / DEG)
    on = fit_verdict({"a": 1e-4, "h": 1e-4}, floors, ["h"], "Try more.", beyond)
    assert on.converged and on.advice == ""
    assert len(on.to_json()["held_out_beyond_training"]) == len(REGIMES)


def test_diagnose_states_the_regimes_beyond_only_beside_an_error_above_the_noise():
    train, held = [_run("a", 1.0, seed=1)], [_run("h", 2.0, seed=1)]
    off = {
        "converged": False,
        "verdict": "held-out RMS error 3.00 x the noise floor: NOT CONVERGED",
    }
    _with_coverage(off, train, held, 1e-4)
    assert "go faster than the training runs in regime(s) R+" in off["verdict"]
    assert len(off["held_out_beyond_training"]) == len(REGIMES)
    on = {"converged": True, "verdict": "at the noise"}
    _with_coverage(on, train, held, 1e-4)
    assert on["verdict"] == "at the noise"
    assert len(on["held_out_beyond_training"]) == len(REGIMES)


def test_identify_on_a_reference_axis_whose_held_out_run_is_faster(tmp_path):
    """Reference seed 101 (0.034 s axis): the held-out multisine reaches
    2.5-4x the cosine training runs' speeds in every regime (docs/identification.md
    "Stop 37"); the JSON of `identify --validate` names them from the data."""
    assert (
        main(["generate", "--reference", "--seed", "101", "--out", str(tmp_path), "--quiet"]) == 0
    )
    js = tmp_path / "p.json"
    argv = ["identify", str(tmp_path / "train1.csv"), str(tmp_path / "train2.csv")]
    argv += ["--validate", str(tmp_path / "heldout.csv"), "--out", str(tmp_path / "p.yaml")]
    assert main(argv + ["--json", str(js), "--quiet", "--no-report"]) == 0
    verdict = json.loads(js.read_text())["verdict"]
    listed = verdict["held_out_beyond_training"]
    assert [b["regime"] for b in listed] == list(REGIMES)
    for b in listed:
        assert b["held_out_reach_deg_s"] > 2.0 * b["training_reach_deg_s"]
    if not verdict["converged"]:
        assert verdict["advice"].startswith("The held-out runs go faster")


def test_a_fixed_side_names_only_its_own_regimes():
    """A freely spinning motor read with ``--side right`` (HSM150): every
    sample is on the right, whatever the angle's sign."""
    train, held = [_run("a", 1.0, seed=1)], [_run("h", 2.0, seed=1)]
    right = beyond_training(sides_as_read(train, "right"), sides_as_read(held, "right"), 1e-4)
    assert [b.regime for b in right] == ["R+", "R-"]
    left = beyond_training(sides_as_read(train, "left"), sides_as_read(held, "left"), 1e-4)
    assert [b.regime for b in left] == ["L+", "L-"]
    # The measured side is read as the angle's sign (no fusion): all four.
    both = beyond_training(sides_as_read(train, "measured"), sides_as_read(held, "measured"), 1e-4)
    assert [b.regime for b in both] == list(REGIMES)


def test_a_wrapped_side_reads_the_angle_modulo_a_turn():
    train = _run("a", 1.0, seed=1)
    turned = MeasuredData("a", train.t, train.u, train.omega, train.angle + 2 * np.pi, None, DT)
    (read,) = sides_as_read([turned], "wrap")
    np.testing.assert_allclose(read.angle, train.angle, atol=1e-12)
