"""The regime prior of identify's refinement (`regime_prior_residuals`):
a weak Gaussian prior tying the regimes' friction quantities together."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isp_twin.errors import ParameterError
from isp_twin.identification.fit import Settings
from isp_twin.identification.search_space import PRIOR_FIELDS, regime_prior_residuals

NOISE = 2e-3  # rad/s


def test_equal_regimes_cost_nothing_and_pole_and_gain_are_free():
    p = regime_prior_residuals(4, 3.0, NOISE)
    z = np.tile(np.array([-3.0, -9.0, -6.0, -7.0, 1.5]), 4)
    np.testing.assert_allclose(p @ z, 0.0, atol=1e-15)
    # The pole and the gain (fields 0, 1) are never tied.
    for f in set(range(5)) - set(PRIOR_FIELDS):
        assert not p[:, f::5].any()


@pytest.mark.parametrize("field", PRIOR_FIELDS)
def test_one_regime_off_by_the_spread_costs_three_quarters_of_a_noise_variance(field):
    """Deviations from the mean of (d, 0, 0, 0) are (3d, -d, -d, -d)/4: their
    squares sum to 0.75 d^2; d = log(spread) is one prior deviation."""
    spread = 3.0
    p = regime_prior_residuals(4, spread, NOISE)
    z = np.zeros(20)
    z[field] = math.log(spread)
    assert float(np.sum((p @ z) ** 2)) == pytest.approx(0.75 * NOISE**2, rel=1e-12)


def test_no_rows_without_a_spread_a_second_regime_or_a_noise():
    assert regime_prior_residuals(4, None, NOISE).shape == (0, 20)
    assert regime_prior_residuals(1, 3.0, NOISE).shape == (0, 5)
    assert regime_prior_residuals(3, 3.0, 0.0).shape == (0, 15)


@pytest.mark.parametrize("spread", [1.0, 0.5, float("nan")])
def test_a_spread_is_a_factor_above_one(spread):
    with pytest.raises(ParameterError, match="regime spread"):
        Settings(regime_spread=spread)
