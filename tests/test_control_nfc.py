"""The friction feed-forward of Eq. 11-14."""

import math

import pytest

from isp_twin.control.nfc import FrictionFeedForward
from isp_twin.model.parameters import REGIMES
from isp_twin.units import DEG


def paper_friction_digits(regime, omega_deg_s):
    """Eq. 5 / Ke straight from the paper's Table 2 form (independent of RateParams)."""
    return (regime.Tc + (regime.Ts - regime.Tc) * math.exp(-regime.alpha * omega_deg_s)) / regime.Ke


@pytest.fixture
def axis(paper_params):
    return paper_params.axis("inner_az")


@pytest.mark.parametrize(
    "name, omega_deg_s, angle",
    [
        ("R+", 2.0, 0.01),
        ("R-", -2.0, 0.01),
        ("L+", 0.7, -0.01),
        ("L-", -5.0, 0.0),
    ],
)
def test_u_c1_is_the_table2_friction_over_ke_of_the_regime(axis, name, omega_deg_s, angle):
    nfc = FrictionFeedForward(axis.rate_params(), gamma=1.0)
    expected = paper_friction_digits(axis.regime(name), abs(omega_deg_s))
    got = nfc.friction_digits(omega_deg_s * DEG, 0.0, angle)
    assert got == pytest.approx(math.copysign(expected, omega_deg_s), rel=1e-9)


def test_at_rest_u_c1_equals_the_feedback_up_to_the_breakaway(axis):
    nfc = FrictionFeedForward(axis.rate_params(), gamma=1.0)
    ts_over_ke = axis.regime("L-").Ts / axis.regime("L-").Ke
    assert nfc.friction_digits(0.0, -50.0, -0.01) == pytest.approx(-50.0)
    assert nfc.friction_digits(0.0, -5000.0, -0.01) == pytest.approx(-ts_over_ke, rel=1e-9)


def test_eq12_smooths_over_four_samples_and_eq13_scales_by_gamma(axis):
    gamma = 0.95
    nfc = FrictionFeedForward(axis.rate_params(), gamma=gamma)
    w = 3.0 * DEG
    u1 = nfc.friction_digits(w, 0.0, 0.01)
    outs = [nfc.step(w, 0.0, 0.01) for _ in range(6)]
    # a step in u_c1 enters the 4-tap mean one tap per sample (Eq. 12)
    assert outs == pytest.approx([gamma * u1 * min(k + 1, 4) / 4 for k in range(6)])


def test_rest_threshold_selects_the_stiction_branch(axis):
    nfc = FrictionFeedForward(axis.rate_params(), gamma=1.0, rest_rate=0.1 * DEG)
    assert nfc.friction_digits(0.05 * DEG, 10.0, 0.01) == pytest.approx(10.0)
    assert nfc.friction_digits(0.5 * DEG, 10.0, 0.01) > 100.0


@pytest.mark.parametrize("gamma", [0.0, 1.2, -0.5])
def test_gamma_outside_zero_one_is_rejected(axis, gamma):
    with pytest.raises(ValueError, match="gamma"):
        FrictionFeedForward(axis.rate_params(), gamma=gamma)


def test_regime_order_matches_the_parameter_file(axis):
    nfc = FrictionFeedForward(axis.rate_params(), gamma=1.0)
    for i, name in enumerate(REGIMES):
        r = axis.regime(name)
        assert nfc.static_digits[i] == pytest.approx(r.Ts / r.Ke, rel=1e-9)
