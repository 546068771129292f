"""The estimation engine's stages on problems with known answers: interval
coverage over many random draws, the information criterion's algebra, and
the way from a fitted vector to a parameter file and back."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isp_twin.estimation.information import bic, parameter_penalty
from isp_twin.estimation.intervals import confidence_intervals, lag1_correlation
from isp_twin.estimation.parameter_file import fitted_axis, stored_form
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    EffectSpec,
    FittedWith,
    load_parameters,
    save_parameters,
)

_RECORD = FittedWith(1, False, False, False, False, 0.0)


def _ar1(rng: np.random.Generator, n: int, rho: float) -> np.ndarray:
    e = rng.normal(size=n)
    out = np.empty(n)
    out[0] = e[0] / math.sqrt(1 - rho**2)
    for i in range(1, n):
        out[i] = rho * out[i - 1] + e[i]
    return out


@pytest.mark.parametrize("rho", [0.0, 0.8])
def test_intervals_cover_the_true_parameters_95_percent_of_the_time(rho):
    # A straight line fitted to white (rho 0) or AR(1) noise (rho 0.8, where
    # the plain Gauss-Newton interval covers 47 % of these draws): 400 draws.
    rng = np.random.default_rng(7)
    n, beta = 1500, np.array([0.3, -1.2])
    x = np.linspace(-1.0, 1.0, n)
    jac = np.column_stack([np.ones(n), x])
    inside = []
    for _ in range(400):
        y = jac @ beta + 0.1 * _ar1(rng, n, rho)
        fit = np.linalg.lstsq(jac, y, rcond=None)[0]
        iv = confidence_intervals(jac, jac @ fit - y, [0, n])
        inside.append(np.abs(fit - beta) <= iv.half_width)
    coverage = np.mean(inside)
    assert 0.92 <= coverage <= 0.98


def test_intervals_need_the_inflation_for_correlated_residuals():
    # Same AR(1) draw: the inflated half-width over the white-noise formula
    # is sqrt((1+rho)/(1-rho)) = 3 for rho = 0.8, up to the estimate of rho.
    rng = np.random.default_rng(3)
    n = 20000
    e = _ar1(rng, n, 0.8)
    jac = np.ones((n, 1))
    r = e - e.mean()
    assert lag1_correlation(r, [0, n]) == pytest.approx(0.8, abs=0.02)
    wide = confidence_intervals(jac, r, [0, n]).half_width[0]
    plain = 1.96 * np.std(r, ddof=1) / math.sqrt(n)
    assert wide / plain == pytest.approx(3.0, rel=0.05)


def test_correlation_is_measured_inside_runs_only():
    # Two runs, each a constant: no lag-1 correlation inside either run's
    # deviations from its own mean (a jump at the boundary would fake one).
    r = np.r_[np.zeros(50) + 1.0, np.zeros(50) - 1.0]
    r = r + np.tile([0.1, -0.1], 50)
    assert lag1_correlation(r, [0, 50, 100]) == pytest.approx(-1.0, abs=0.05)


def test_a_parameter_the_data_never_touch_has_no_interval():
    rng = np.random.default_rng(0)
    jac = np.column_stack([np.ones(100), np.zeros(100)])
    iv = confidence_intervals(jac, rng.normal(size=100), [0, 100])
    assert np.isfinite(iv.half_width[0]) and np.isnan(iv.half_width[1])
    assert np.isnan(iv.at_floor[1])


def test_noise_floor_widens_intervals_of_a_noise_free_fit():
    jac = np.column_stack([np.ones(100), np.linspace(0, 1, 100)])
    iv = confidence_intervals(jac, np.zeros(100), [0, 100], floor=0.1)
    assert np.all(iv.half_width == 0.0) and np.all(iv.at_floor > 0.0)


def test_bic_charges_ln_m_per_parameter():
    m = 1000
    assert bic(2.0, m, 5) - bic(2.0, m, 4) == pytest.approx(math.log(m))
    assert parameter_penalty(3, m) == pytest.approx(3 * math.log(m))
    # A parameter pays for itself exactly when it lowers the SSE by m^(-1/m).
    assert bic(2.0 * m ** (-1.0 / m), m, 5) == pytest.approx(bic(2.0, m, 4))
    assert bic(2.0, m, 4) == pytest.approx(m * math.log(2.0 / m) + 4 * math.log(m))
    assert math.isfinite(bic(0.0, m, 4))  # a perfect fit is not -inf


def test_a_fitted_vector_comes_back_from_its_file_as_stored_form(paper_params, tmp_path):
    # The file holds 6 significant digits of the paper form: what load gives
    # back is stored_form of the fitted vector (to the last bits of the unit
    # conversion), within 6 digits of it but not equal.
    prior = paper_params.axis("inner_az")
    rng = np.random.default_rng(1)
    x = prior.rate_params().to_vector() * rng.uniform(0.9, 1.1, RATE_LAYOUT.size)
    x[RATE_LAYOUT.field_index("pole") :: RATE_LAYOUT.n_fields] = np.minimum(
        x[RATE_LAYOUT.field_index("pole") :: RATE_LAYOUT.n_fields], 0.999
    )
    ci = np.abs(x) * 0.01
    record = FittedWith(10, True, True, True, False, 0.5)
    cog = EffectSpec("cogging", {"amplitude_rad_s2": 0.01, "period_rad": 0.1, "phase_rad": 0.0})
    axis = fitted_axis(prior, x, ci, [cog], record, "test")
    path = save_parameters(paper_params.with_axis("inner_az", axis), tmp_path / "p.yaml")
    back = load_parameters(path).axis("inner_az")
    b = np.array([r.b for r in prior.regimes])
    stored = stored_form(x, b)
    assert np.allclose(back.rate_params().to_vector(), stored, rtol=1e-13, atol=0.0)
    assert np.allclose(stored, x, rtol=1e-5) and not np.allclose(stored, x, rtol=1e-9)
    assert back.fitted_with == record and back.note == "test"
    assert [e.name for e in back.effects] == ["cogging"]
    assert all(math.isnan(c.b) for c in axis.ci95)
    # Ke's half-width scales like Ke: b·Ke's relative width is kept.
    assert axis.ci95[0].Ke / axis.regimes[0].Ke == pytest.approx(0.01)


def test_a_regime_the_fit_froze_keeps_the_prior_and_has_no_interval(paper_params):
    prior = paper_params.axis("inner_az")
    x = 1.05 * prior.rate_params().to_vector()
    axis = fitted_axis(
        prior, x, np.full(x.size, 0.1), (), _RECORD, "", identified=(True, True, False, True)
    )
    assert axis.regimes[2] == prior.regimes[2] and axis.ci95[2] is None
    assert axis.regimes[0] != prior.regimes[0] and axis.identified == (True, True, False, True)
    kept = fitted_axis(prior, x, np.full(x.size, 0.1), (), _RECORD, "")
    assert kept.identified == prior.identified and all(c is not None for c in kept.ci95)
