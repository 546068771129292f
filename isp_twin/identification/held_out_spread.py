"""What the training runs leave open on a held-out run.

A held-out run can be far from the noise for two reasons: the model lacks
something (an effect, a fit that has not converged), or the training runs
do not determine what the held-out run depends on: a breakaway level the
held-out run grazes, a Stribeck curve at speeds no training run reaches.
On reference clean seed 146 the fit reads 1.47 noise floors held out; its
regime R+ has b·Ts 0.2 % below the truth's, a tenth of its 95 % interval,
and with that one number set to the truth's the held-out run reads 1.00.

To tell the two apart, `held_out_spread` draws parameter sets around the
fit from the intervals' covariance (`IdentificationResult.covariance`),
mapped into the search variables (`to_z`) so that every draw is physical
(levels > 0, Ts >= Tc, alpha > 0); it keeps the draws the training runs
cannot tell from the fit: their Eq. 9 sum of squares within the
chi-square bound (`LEVEL`, as many degrees of freedom as free quantities)
of the fit's, in units of the residual variance inflated for the
residuals' correlation as the intervals are. The covariance is a local
(linear) picture of a cost that stick/slip makes piecewise, so the bound,
not the covariance, decides which models are allowed. The held-out runs'
RMS errors over their noise floors at the allowed draws are the spread.

Cost: one simulation of the training runs and of each held-out run per
draw (`DRAWS`), in chunks of `CHUNK` parameter sets; the training runs
again for each smaller covariance tried (`SHRINK`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from isp_twin.estimation.simulation_error import RunStack
from isp_twin.estimation.verdict import HeldOutSpread, noise_floor_of
from isp_twin.identification.cost import rmse, run_stack
from isp_twin.identification.fit import IdentificationResult
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.search_space import from_z, to_z
from isp_twin.model.parameters import RATE_LAYOUT, RateParams

__all__ = ["DRAWS", "LEVEL", "held_out_spread", "parameter_draws"]

#: Parameter sets drawn around the fit (the fit itself is one more).
DRAWS = 64
#: The chi-square level of the training runs' bound on the allowed draws.
LEVEL = 0.95
#: Factors on the covariance, tried in turn until the training runs allow
#: more than half of the draws: a direction the linear picture makes far
#: too wide (the cost is piecewise) would otherwise leave only the fit
#: (reference clean seeds 145 and 148: 1 of 65 at the full covariance).
SHRINK = (1.0, 1 / 4, 1 / 16, 1 / 64)
#: Largest standard deviation of a search variable in the draws (a factor
#: e^2.3 = 10): the quantities the intervals call not identifiable have a
#: linear-picture deviation of 100 and more in log (reference clean seed
#: 145, regime R+: b·(Ts-Tc) 236, alpha 141), and no draw near them fits
#: the training runs. The correlations are kept.
Z_SD_CAP = np.log(10.0)
#: Allowed draws (the fit among them) at or below which no spread is read:
#: the covariance's picture of the cost failed (the quantiles are NaN).
MIN_ALLOWED = DRAWS // 4
#: Parameter sets simulated at once (memory: CHUNK x samples x 8 bytes a row).
CHUNK = 16
#: Relative step of the derivative of `to_z` (no simulation: exact enough).
_STEP = 1e-7


def parameter_draws(x: np.ndarray, cov: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
    """`n` draws around free quantities `x` (k,) with covariance `cov` (k, k)
    in the rate form's units, drawn in the search variables (`to_z`, the
    covariance carried there by the derivative of `to_z` at x) and mapped
    back: (n, k), the pole kept in [0, 1). A quantity with a NaN variance (not determined) gets no
    spread of its own (it moves only through the search variables it shares,
    as b·Ts with b·Tc); a search variable's deviation is capped at `Z_SD_CAP`.
    """
    x = np.asarray(x, float)
    h = _STEP * np.maximum(np.abs(x), 1e-12)
    t = (to_z(x + np.diag(h)) - to_z(x - np.diag(h))).T / (2 * h)  # dz/dx, (k, k)
    blind = ~np.isfinite(np.diag(cov))
    c = np.where(np.isfinite(cov), cov, 0.0)
    c[blind, :] = c[:, blind] = 0.0
    cz = t @ c @ t.T
    sd = np.sqrt(np.clip(np.diag(cz), 0.0, None))
    cap = np.minimum(1.0, Z_SD_CAP / np.maximum(sd, 1e-300))
    cz = cz * np.outer(cap, cap)
    rng = np.random.default_rng(seed)
    z = rng.multivariate_normal(to_z(x), (cz + cz.T) / 2, size=n, method="eigh")
    # log(1 - a) <= 0: the pole a stays in [0, 1) (the model's a ** (1/m) has
    # no real value below 0).
    z[:, 0 :: RATE_LAYOUT.n_fields] = np.minimum(z[:, 0 :: RATE_LAYOUT.n_fields], 0.0)
    return from_z(z)


def _stack(result: IdentificationResult, runs: Sequence[MeasuredData]) -> RunStack:
    """`runs` stacked as the fit read them (its side source, rest level, timing, integration)."""
    s = result.settings
    return run_stack(runs, s.side_source, s.rest_rate_deg_s, result.timing, result.integration)


def _errors(result: IdentificationResult, rates: np.ndarray, stack: RunStack) -> np.ndarray:
    """RMS error [rad/s] over the stacked runs together of the full rate vectors `rates` (P, 20)."""
    out = []
    for lo in range(0, len(rates), CHUNK):
        params = RateParams.from_vector(rates[lo : lo + CHUNK])
        out.append(np.atleast_1d(rmse(params, stack, effects=result.effects)))
    return np.concatenate(out)


def held_out_spread(
    result: IdentificationResult,
    train: Sequence[MeasuredData],
    validation: Sequence[MeasuredData],
    seed: int = 0,
) -> tuple[HeldOutSpread, ...]:
    """Each validation run's error over its noise floor at the models the
    training runs allow (module doc); NaN quantiles where they allow
    `MIN_ALLOWED` draws or fewer at every `SHRINK`; () without validation
    runs or a covariance."""
    from scipy.stats import chi2

    k = result.covariance.shape[0]
    if not validation or not train or k == 0:
        return ()
    mask = RATE_LAYOUT.regime_mask(np.array(result.regime_identified))
    full = result.rate.to_vector()
    m = sum(len(d) - 1 for d in train)
    rho = result.rho if 0 < result.rho < 1 else 0.0
    train_stack = _stack(result, train)  # once for every covariance tried
    for scale in SHRINK:
        rates = np.tile(full, (DRAWS + 1, 1))
        rates[1:, mask] = parameter_draws(full[mask], result.covariance * scale, DRAWS, seed)
        sse = _errors(result, rates, train_stack) ** 2 * m
        variance = sse[0] / max(m - k, 1) * (1 + rho) / (1 - rho)
        allowed = sse - sse[0] <= chi2.ppf(LEVEL, k) * variance
        allowed[0] = True
        if allowed.sum() > DRAWS // 2:
            break
    n_allowed = int(allowed.sum())
    out = []
    for d in validation:
        quantiles = (np.nan,) * 3
        if n_allowed > MIN_ALLOWED:
            ratio = _errors(result, rates[allowed], _stack(result, [d])) / noise_floor_of([d.omega])
            quantiles = tuple(float(q) for q in np.quantile(ratio, [0.05, 0.5, 0.95]))
        out.append(HeldOutSpread(d.name, *quantiles, n_allowed, DRAWS + 1))
    return tuple(out)
