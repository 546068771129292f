"""Properties of the improved Stribeck law (Eq. 5)."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.model.friction import (
    SIDE_L,
    SIDE_R,
    friction_torque,
    regime_index,
    regime_of,
    side_of,
    sliding,
    sliding_friction,
    stiction,
    stiction_friction,
    stribeck,
    stribeck_magnitude,
)
from isp_twin.model.parameters import REGIMES

TS = np.array([5.563, 7.117, 2.743, 4.254])  # Table 2, R+ R- L+ L-
TC = np.array([3.176, 4.016, 1.950, 3.569])
ALPHA = np.array([0.427, 0.263, 0.774, 0.166])


@pytest.mark.parametrize(
    "angle, direction, expected",
    [
        (1.0, 1.0, "R+"),
        (1.0, -1.0, "R-"),
        (-1.0, 1.0, "L+"),
        (-1.0, -1.0, "L-"),
        (0.0, 1.0, "R+"),
        (0.0, -1.0, "L-"),
        (0.0, 0.0, "L+"),
    ],
)
def test_regime_follows_side_and_direction(angle, direction, expected):
    # Eq. 5: Y < 0 is L, Y > 0 is R. At Y = 0 (Eq. 5 puts it in L) a motion
    # enters the side of its direction: a positive one is at once in Y > 0.
    assert REGIMES[int(regime_index(angle, direction))] == expected


def test_stribeck_curve_runs_from_static_to_coulomb():
    speeds = np.linspace(0.0, 200.0, 2001)
    for r in range(4):
        curve = stribeck_magnitude(speeds, TS[r], TC[r], ALPHA[r])
        assert curve[0] == pytest.approx(TS[r])
        assert curve[-1] == pytest.approx(TC[r], rel=1e-6)
        # Ts > Tc in every regime of Table 2: the curve decreases monotonically.
        assert np.all(np.diff(curve) <= 0)


def test_sliding_friction_is_odd_and_continuous_within_a_branch():
    w = np.linspace(1e-6, 50.0, 500)
    for r in range(4):
        pos = sliding_friction(w, TS[r], TC[r], ALPHA[r])
        neg = sliding_friction(-w, TS[r], TC[r], ALPHA[r])
        np.testing.assert_allclose(neg, -pos)
        assert np.max(np.abs(np.diff(pos))) < 0.05 * TS[r]
        # The sliding branch meets the breakaway torque as the rate goes to 0.
        assert pos[0] == pytest.approx(TS[r], rel=1e-5)


def test_stiction_balances_the_drive_up_to_breakaway():
    drive = np.linspace(-10, 10, 401)
    f = stiction_friction(drive, 4.0)
    inside = np.abs(drive) <= 4.0
    np.testing.assert_array_equal(f[inside], drive[inside])
    np.testing.assert_array_equal(f[~inside], 4.0 * np.sign(drive[~inside]))


@pytest.mark.parametrize("r", range(4))
def test_breakaway_threshold_per_regime(r):
    angle = 1.0 if REGIMES[r][0] == "R" else -1.0
    sign = 1.0 if REGIMES[r][1] == "+" else -1.0
    below = sign * 0.99 * TS[r]
    above = sign * 1.01 * TS[r]
    torque, regime = friction_torque(0.0, below, angle, TS, TC, ALPHA)
    assert regime == r and torque == pytest.approx(below)  # held: net torque 0
    torque, regime = friction_torque(0.0, above, angle, TS, TC, ALPHA)
    assert regime == r and above - torque == pytest.approx(sign * 0.01 * TS[r])


def test_zero_drive_at_rest_gives_zero_friction():
    torque, _ = friction_torque(0.0, 0.0, 0.5, TS, TC, ALPHA)
    assert torque == 0.0


def test_batched_parameters_broadcast():
    ts = np.stack([TS, 2 * TS])
    torque, regime = friction_torque(np.array([0.0, 0.0]), np.array([3.0, 3.0]), 1.0, ts, TC, ALPHA)
    assert regime.tolist() == [0, 0]
    np.testing.assert_allclose(torque, [3.0, 3.0])


# ---------------------------------------------------------- scalar vs array form
# One law, two forms: the per-step callers (twin, NFC, compiled loop) use the
# scalar functions, the batched ones (axis model, identification) the arrays.

ANGLES = (0.35, 1e-9, 0.0, -1e-9, -0.35)  # R, R, the boundary (by direction), L, L
RATES = (2.1, 0.04, 1e-12, 0.0, -1e-12, -0.04, -2.1)
DRIVES = (9.0, 5.0, 1.0, 0.0, -1.0, -5.0, -9.0)


@pytest.mark.parametrize("alpha", [ALPHA, np.zeros(4)], ids=["table2", "alpha0"])
def test_scalar_and_array_forms_agree_on_every_regime(alpha):
    grid = [(a, w, d) for a in ANGLES for w in RATES for d in DRIVES]
    angle, rate, drive = (np.array(c) for c in zip(*grid))
    torque, regime = friction_torque(rate, drive, angle, TS, TC, alpha)
    assert set(regime.tolist()) == {0, 1, 2, 3}
    for k, (a, w, d) in enumerate(grid):
        side = side_of(a, w if w != 0.0 else d)
        r = regime_of(side, w if w != 0.0 else d)
        expected = sliding(w, TS[r], TC[r], alpha[r]) if w != 0.0 else stiction(d, TS[r])
        assert r == regime[k]
        # np.exp and math.exp may round differently in the last bit.
        assert torque[k] == pytest.approx(expected, rel=1e-15, abs=0.0)
        if w != 0.0:
            magnitude = stribeck(abs(w), TS[r], TC[r], alpha[r])
            assert magnitude == pytest.approx(
                stribeck_magnitude(abs(w), TS[r], TC[r], alpha[r]), rel=1e-15
            )
            assert np.sign(expected) == np.sign(w)


def test_scalar_side_and_regime_follow_fig3():
    assert [side_of(a, 1.0) for a in (1.0, 0.0, -1.0)] == [SIDE_R, SIDE_R, SIDE_L]
    assert [side_of(a, -1.0) for a in (1.0, 0.0, -1.0)] == [SIDE_R, SIDE_L, SIDE_L]
    assert [side_of(a, 0.0) for a in (1.0, 0.0, -1.0)] == [SIDE_R, SIDE_L, SIDE_L]
    names = [REGIMES[regime_of(s, d)] for s in (SIDE_R, SIDE_L) for d in (1.0, 0.0, -1.0)]
    assert names == ["R+", "R+", "R-", "L+", "L+", "L-"]


def test_scalar_stiction_clips_at_breakaway_and_alpha0_is_coulomb():
    assert stiction(3.0, 2.0) == 2.0 and stiction(-3.0, 2.0) == -2.0
    assert stiction(1.5, 2.0) == 1.5 and stiction(0.0, 2.0) == 0.0
    assert stribeck(0.0, 2.0, 1.0, 0.5) == 2.0
    assert stribeck(7.0, 2.0, 1.0, 0.0) == 2.0  # alpha 0: no decay from Ts
    assert sliding(-0.3, 2.0, 1.0, 0.5) == -sliding(0.3, 2.0, 1.0, 0.5)
