"""Gyro bias and scale error measured against the angle sensor (the `sensor_bias` effect).

The resolver angle does not see the gyro's errors: over a run
``theta(t_k) - theta(t_0)`` is the integral of the true rate. The gyro reads
``omega_m = b + (1 + s) * omega``, so with ``S_k = dt * sum_{j<=k} omega_m[j]``
(its reading integrated)::

    theta_k = c_run + S_k / (1 + s) - b / (1 + s) * t_k + d * dt * omega_m[k] + e_k

one linear regression per data set, independent of the friction model. The
intercept ``c_run`` is per run (the resolver's zero is unknown); ``d`` takes up
where within its sample the gyro reading sits (a reading averaged over the
sample just ended sums exactly to the angle change, ``d = 0``; a point-sampled
one is half a sample late, ``d ~ -0.5``), so neither timing biases s and b. The
error ``e`` is the resolver's quantization (white, steps of one count) plus the
gyro noise integrated (a random walk, ``sigma * sqrt(dt * t)``): both tiny
against angle excursions of degrees, so the slope is not attenuated. The
residuals are serially correlated (the random walk, quantization of a slowly
moving angle), so the confidence intervals use a Newey-West (Bartlett)
covariance per run, not the white-noise one.

Why a levels regression and not one on window increments (what
`SensorBias.guesses` did before): the bias is the slope against time, and the
long baseline of a whole run determines it ~100x better than short windows,
whose differencing doubles the quantization noise (dev seeds 1000-1019,
`tests/test_gyro_error.py`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from isp_twin.errors import ParameterError
from isp_twin.estimation.verdict import SCALE_DIFFERENCE, noise_floor_of
from isp_twin.identification.measured import MeasuredData
from isp_twin.model.parameters import RateParams

__all__ = [
    "GyroError",
    "gyro_error_estimate",
    "rate_behind_gyro_error",
    "reading_error",
]

#: Student-t-free 95 % factor (thousands of samples per run).
_Z95 = 1.959964


@dataclass(frozen=True)
class GyroError:
    """Gyro error estimated against the angle (`gyro_error_estimate`).

    Attributes:
        bias_rad_s: b [rad/s].
        scale: s [1] (0 = exact), ``omega_m = b + (1 + s) * omega``.
        bias_ci95: 95 % half-width of b [rad/s].
        scale_ci95: 95 % half-width of s [1].
        timing_samples: d, where the reading sits in its sample [samples]
            (0: averaged over the sample just ended).
        rms_rad: RMS residual of the angle regression [rad].
    """

    bias_rad_s: float
    scale: float
    bias_ci95: float
    scale_ci95: float
    timing_samples: float
    rms_rad: float

    def contains_null(self) -> bool:
        """True when both intervals contain the exact gyro (b = 0, s = 0)."""
        return abs(self.bias_rad_s) <= self.bias_ci95 and abs(self.scale) <= self.scale_ci95

    def corrected(self, omega: np.ndarray) -> np.ndarray:
        """The true rate implied by a reading, ``(omega_m - b) / (1 + s)`` [rad/s]."""
        return (np.asarray(omega, float) - self.bias_rad_s) / (1.0 + self.scale)


def gyro_error_estimate(data: Sequence[MeasuredData]) -> GyroError:
    """Regress the angle on the integrated gyro reading and time (module doc).

    Args:
        data: the runs; each needs the measured angle (not one integrated
            from the rate) and the same sample period.

    Raises:
        ParameterError: no run with at least 10 samples, or the angle does
            not move (the scale is then undetermined).
    """
    runs = [d for d in data if len(d) >= 10]
    if not runs:
        raise ParameterError("gyro error: no run with at least 10 samples")
    n_runs = len(runs)
    blocks, targets = [], []
    for i, d in enumerate(runs):
        w = np.asarray(d.omega, float)
        # S_0 = 0: the angle change up to sample k is the readings 1..k.
        s_int = d.dt * np.concatenate(([0.0], np.cumsum(w[1:])))
        cols = np.zeros((len(d), n_runs + 3))
        cols[:, i] = 1.0
        cols[:, n_runs] = s_int
        cols[:, n_runs + 1] = d.t - d.t[0]
        cols[:, n_runs + 2] = d.dt * w
        blocks.append(cols)
        targets.append(np.asarray(d.angle, float))
    x = np.vstack(blocks)
    y = np.concatenate(targets)
    norm = np.linalg.norm(x, axis=0)
    if norm[n_runs] == 0.0 or np.ptp(y) == 0.0:
        raise ParameterError("gyro error: the angle does not move in the data")
    # Columns scaled to unit norm: sums of radians against seconds.
    coef = np.linalg.lstsq(x / norm, y, rcond=None)[0] / norm
    resid = y - x @ coef
    inv_scale, slope_t, d_timing = coef[n_runs : n_runs + 3]
    cov = _covariance(x, resid, runs, abs(inv_scale))
    # Delta method: s = 1/a - 1, b = -beta/a.
    ja = np.array([-1.0 / inv_scale**2, 0.0])
    jb = np.array([slope_t / inv_scale**2, -1.0 / inv_scale])
    sub = cov[n_runs : n_runs + 2, n_runs : n_runs + 2]
    return GyroError(
        bias_rad_s=float(-slope_t / inv_scale),
        scale=float(1.0 / inv_scale - 1.0),
        bias_ci95=float(_Z95 * np.sqrt(max(jb @ sub @ jb, 0.0))),
        scale_ci95=float(_Z95 * np.sqrt(max(ja @ sub @ ja, 0.0))),
        timing_samples=float(d_timing),
        rms_rad=float(np.sqrt(np.mean(resid**2))),
    )


def _covariance(x: np.ndarray, resid: np.ndarray, runs: list[MeasuredData], a: float):
    """Covariance of the least-squares coefficients under the error model of
    the module doc, per run: ``a * (gyro noise integrated)``, a random walk
    of variance ``a^2 sigma^2 dt^2 k`` at sample k, plus white angle noise
    of variance v (quantization); runs independent.

    sigma is the gyro's white noise (`noise_floor_of`), v what the residual's
    sample-to-sample differences leave beyond it. The sandwich
    ``(X'X)^-1 X' Sigma X (X'X)^-1`` is exact for that Sigma; the random-walk
    part ``min(i, j)`` is ``C'C`` with C the reversed cumulative sums of X.
    """
    xtx_inv = np.linalg.pinv(x.T @ x)
    meat = np.zeros((x.shape[1], x.shape[1]))
    start = 0
    for d in runs:
        n = len(d)
        xr, rr = x[start : start + n], resid[start : start + n]
        start += n
        sigma = noise_floor_of([np.asarray(d.omega, float)], SCALE_DIFFERENCE)
        walk = (a * sigma * d.dt) ** 2
        white = max((np.mean(np.diff(rr) ** 2) - walk) / 2.0, 0.0)
        # The walk starts at sample 1 (sample 0 is the run's own intercept).
        tail = np.cumsum(xr[::-1], axis=0)[::-1][1:]
        meat += walk * (tail.T @ tail) + white * (xr.T @ xr)
    return xtx_inv @ meat @ xtx_inv


def reading_error(run: MeasuredData) -> GyroError | None:
    """The gyro error of one run measured against its angle (`gyro_error_estimate`),
    or None where its intervals contain the exact gyro or the run cannot tell
    (too short, the angle does not move): the correction the angle fusion
    applies to the reading (`isp_twin.identification.side_angle.fused_angle`)."""
    try:
        est = gyro_error_estimate([run])
    except ParameterError:
        return None
    return None if est.contains_null() else est


def rate_behind_gyro_error(fitted: RateParams, est: GyroError) -> RateParams:
    """Eq. 6 parameters of the true rate, from those fitted to a gyro reading
    ``m = b + (1 + s) w``.

    Substituting ``w = (m - b)/(1 + s)`` into Eq. 6 gives, for the reading,
    ``m[k] = a m[k-1] + (1 - a) b + (1 + s)(gain u - friction)``: gain and
    levels scaled by (1 + s), the curve factor by 1/(1 + s), and the bias a
    constant drive ``(1 - a) b``, i.e. the Coulomb and static levels of the +
    regimes lowered and those of the - regimes raised by it. A model fitted
    to the reading has absorbed exactly that (in motion); this undoes it.
    """
    k = 1.0 + est.scale
    a = np.asarray(fitted.pole, float)
    # Regimes R+, R-, L+, L- (`REGIMES`): friction opposes +1, -1, +1, -1.
    direction = np.array([1.0, -1.0, 1.0, -1.0])
    shift = direction * (1.0 - a) * est.bias_rad_s
    floor = 1e-12
    return RateParams(
        pole=a,
        gain=np.asarray(fitted.gain, float) / k,
        static=np.maximum((np.asarray(fitted.static, float) + shift) / k, floor),
        coulomb=np.maximum((np.asarray(fitted.coulomb, float) + shift) / k, floor),
        alpha=np.asarray(fitted.alpha, float) * k,
    )
