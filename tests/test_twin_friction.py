"""Friction in the twin: true stick, breakaway at Ts, sliding law, no chatter (Eq. 5).

All on the inner azimuth with the paper's Table 2 parameters
(models/params/paper_table2.yaml), one test per regime R+, R-, L+, L-.
"""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.model.friction import sliding_friction, stribeck_magnitude
from isp_twin.model.parameters import REGIMES, load_parameters
from isp_twin.model.twin import REST_RATE, Twin
from isp_twin.resources import default_parameters_path
from isp_twin.units import DEG

AZ = 0  # inner_az in the twin's GIMBALS order
#: start angle on each regime's side: R = +2 deg, L = -2 deg
START = {"R+": 2 * DEG, "R-": 2 * DEG, "L+": -2 * DEG, "L-": -2 * DEG}
SIGN = {"R+": 1.0, "R-": -1.0, "L+": 1.0, "L-": -1.0}


@pytest.fixture(scope="module")
def twin() -> Twin:
    return Twin(load_parameters(default_parameters_path()))


def breakaway_digits(twin: Twin, regime: int) -> float:
    ax = twin.axes["inner_az"]
    return float(ax.static[regime] / ax.drive_gain[regime])


def run_constant(twin: Twin, name: str, fraction: float, seconds: float):
    r = REGIMES.index(name)
    twin.reset({"inner_az": START[name]})
    u = SIGN[name] * fraction * breakaway_digits(twin, r)
    n = int(round(seconds / twin.dt))
    rate, angle, regime = np.empty(n), np.empty(n), np.empty(n, dtype=int)
    for k in range(n):
        twin.step([u, 0.0, 0.0, 0.0])
        s = twin.state()
        rate[k], angle[k], regime[k] = s.rate[AZ], s.angle[AZ], s.regime[AZ]
    return rate, angle, regime


@pytest.mark.parametrize("name", REGIMES)
def test_below_breakaway_the_gimbal_truly_sticks(twin, name):
    rate, angle, regime = run_constant(twin, name, 0.9, 2.0)
    assert np.abs(rate).max() < 1e-3 * DEG, f"creep {np.abs(rate).max() / DEG:.2e} deg/s"
    assert abs(angle[-1] - START[name]) < 1e-6 * DEG
    assert np.all(regime == REGIMES.index(name))


@pytest.mark.parametrize("name", REGIMES)
def test_just_above_breakaway_it_moves_the_right_way(twin, name):
    rate, angle, regime = run_constant(twin, name, 1.05, 0.05)
    assert np.all(np.sign(rate) == SIGN[name])
    assert SIGN[name] * (angle[-1] - START[name]) > 0.0
    assert regime[0] == REGIMES.index(name)


@pytest.mark.parametrize("name", REGIMES)
def test_the_first_step_after_breakaway_follows_eq_5(twin, name):
    # From rest, Eq. 5 leaves drive - Ts to accelerate J over one step (Euler).
    r = REGIMES.index(name)
    ax = twin.axes["inner_az"]
    rate, _, _ = run_constant(twin, name, 1.5, twin.dt)
    expected = SIGN[name] * 0.5 * ax.static[r] * twin.dt / ax.inertia
    assert rate[0] == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("name", REGIMES)
def test_the_sliding_friction_is_the_mapped_stribeck_law(twin, name):
    r = REGIMES.index(name)
    ax = twin.axes["inner_az"]
    twin.reset({"inner_az": START[name]})
    u = SIGN[name] * 2.0 * breakaway_digits(twin, r)
    checked = 0
    for _ in range(40):
        before = twin.state()
        twin.step([u, 0.0, 0.0, 0.0])
        after = twin.state()
        w = before.rate[AZ]
        moving = abs(w) > REST_RATE and np.sign(after.rate[AZ]) == np.sign(w)
        if moving and after.regime[AZ] == r:
            expected = sliding_friction(w, ax.static[r], ax.coulomb[r], ax.alpha[r])
            assert after.friction[AZ] == pytest.approx(expected, rel=1e-6)
            frictionloss = twin.model.dof_frictionloss[twin.model.joint("inner_az").dofadr[0]]
            magnitude = stribeck_magnitude(
                abs(after.rate[AZ]), ax.static[r], ax.coulomb[r], ax.alpha[r]
            )
            assert frictionloss == pytest.approx(magnitude, rel=1e-12)
            checked += 1
    assert checked > 10


@pytest.mark.parametrize("side", ["R", "L"])
def test_a_slow_sine_through_reversals_does_not_chatter(twin, side):
    """Each reversal passes through rest; at most one reversal per half period."""
    regimes = [0, 1] if side == "R" else [2, 3]
    amplitude = 1.2 * max(breakaway_digits(twin, r) for r in regimes)
    f_hz, seconds = 1.0, 4.0
    twin.reset({"inner_az": 2 * DEG if side == "R" else -2 * DEG})
    n = int(round(seconds / twin.dt))
    rate, angle = np.empty(n), np.empty(n)
    for k in range(n):
        twin.step([amplitude * np.sin(2 * np.pi * f_hz * k * twin.dt), 0.0, 0.0, 0.0])
        s = twin.state()
        rate[k], angle[k] = s.rate[AZ], s.angle[AZ]
    direction = np.where(np.abs(rate) > REST_RATE, np.sign(rate), 0.0)
    # the end stop may bounce the gimbal back: not friction, left out
    free = np.abs(angle) < 4 * DEG - 0.1 * DEG
    pairs = free[1:] & free[:-1]
    direct_flips = np.sum((direction[1:] * direction[:-1] < 0) & pairs)
    assert direct_flips == 0, "a reversal skipped the stick phase"
    signs = direction[direction != 0]
    reversals = int(np.sum(signs[1:] != signs[:-1]))
    assert 1 <= reversals <= 2 * f_hz * seconds, f"{reversals} reversals"
