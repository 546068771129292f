"""Confidence intervals of a least-squares fit, the one computation.

From the residual Jacobian J (M, n) at the fit and the residuals e (M,):
``cov = s^2 (J^T J)^-1`` with ``s^2 = e.e / (M - n)``, inflated by
``(1 + rho)/(1 - rho)`` for a lag-1 residual correlation rho > 0 (measured
inside each run, not across run boundaries: the effective sample size of an
AR(1) series), and the Student t quantile at the effective degrees of
freedom. The simulation error of a recursive model is correlated over the
axis's time constant (~1/(1-a) samples), so the plain Gauss-Newton interval
is too narrow by up to sqrt((1+rho)/(1-rho)) (docs/identification.md,
"Estimation engine").

A parameter whose Jacobian column is zero (the data never touch it, or the
model could not be simulated around it) has no interval (NaN).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Intervals", "confidence_intervals", "lag1_correlation"]


@dataclass(frozen=True)
class Intervals:
    """Confidence half-widths of a fit's parameters.

    Attributes:
        half_width: half-widths at the requested level, (n,), the
            parameters' unit; NaN where not determined.
        at_floor: the same with the residual variance raised to at least
            the noise floor's square (so noise-free data does not make
            every parameter determined), (n,).
        rho: the residuals' lag-1 correlation inside the runs [1].
        covariance: the parameters' covariance the half-widths come from,
            (n, n), the parameters' unit squared (without the t quantile);
            NaN in the rows and columns of a parameter not determined.
    """

    half_width: np.ndarray
    at_floor: np.ndarray
    rho: float
    covariance: np.ndarray


def lag1_correlation(resid: np.ndarray, breaks: Sequence[int]) -> float:
    """Lag-1 autocorrelation of `resid` (M,) inside each run [breaks[i], breaks[i+1])."""
    num = den = 0.0
    for lo, hi in zip(breaks[:-1], breaks[1:]):
        e = resid[lo:hi] - resid[lo:hi].mean()
        num += float(e[1:] @ e[:-1])
        den += float(e @ e)
    return num / den if den > 0 else 0.0


def confidence_intervals(
    jac: np.ndarray,
    resid: np.ndarray,
    breaks: Sequence[int],
    level: float = 0.95,
    floor: float = 0.0,
) -> Intervals:
    """Half-widths from the Jacobian (module doc).

    Args:
        jac: d residual / d parameter at the fit, (M, n).
        resid: residuals at the fit, (M,).
        breaks: run boundaries in the residual vector, (R+1,) from 0 to M.
        level: confidence level (0.95 gives 95 % half-widths).
        floor: noise floor [residual unit] for `Intervals.at_floor`.
    """
    from scipy.stats import t as student_t

    m, p = jac.shape
    if p == 0:
        return Intervals(np.zeros(0), np.zeros(0), 0.0, np.zeros((0, 0)))
    s2 = float(resid @ resid) / max(m - p, 1)
    rho = lag1_correlation(resid, breaks)
    inflate = (1 + rho) / (1 - rho) if 0 < rho < 1 else 1.0
    n_eff = max(m / inflate, p + 1.0)
    q = float(student_t.ppf(0.5 + level / 2, max(n_eff - p, 1)))
    # Columns scaled to unit norm: the raw J^T J spans ~20 decades and a plain
    # inverse loses the weakly determined directions.
    norm = np.linalg.norm(jac, axis=0)
    blind = ~(norm > 0)
    norm = np.where(blind, 1.0, norm)
    js = jac / norm
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            inv = np.linalg.pinv(js.T @ js, rcond=1e-12, hermitian=True)
    except np.linalg.LinAlgError:
        # Slopes so steep (a model near divergence) that the SVD fails: the
        # parameters are not determined.
        inv = np.full((p, p), np.nan)
    var = np.clip(np.diag(inv), 0, None) / norm**2
    var[blind] = np.nan
    half = q * np.sqrt(s2 * inflate * var)
    at_floor = q * np.sqrt(max(s2, floor**2) * inflate * var)
    cov = s2 * inflate * inv / np.outer(norm, norm)
    cov[blind, :] = cov[:, blind] = np.nan
    return Intervals(half, at_floor, float(rho), cov)
