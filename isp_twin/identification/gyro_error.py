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
from dataclasses import dataclass, replace

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
    "one_gyro_error",
    "fusion_note",
    "fusion_json",
    "AGREEMENT_Z",
    "AGREEMENT_SHARE",
]

#: Two runs' estimates of one gyro's scale error or bias are one error
#: unless they differ by more than `AGREEMENT_Z` standard errors and by more
#: than `AGREEMENT_SHARE` of the larger of them (`one_gyro_error`). The
#: intervals alone are too tight on some axes: reference clean axis 471
#: (no gyro error) reads a scale of +0.026 % +- 0.007 % on train1, and its
#: sensor bias case's three runs differ by 1.3 % of their -2.8 % scale,
#: six standard errors. The resonance axes that need the rule differ by far
#: more than a share of 0.1-0.3 (any of which separated the cells below).
AGREEMENT_Z = 4.0
AGREEMENT_SHARE = 0.2

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


def one_gyro_error(runs: Sequence[MeasuredData]) -> list[MeasuredData]:
    """The runs of one command, with the fusion's correction of the reading
    (`reading_error`, `isp_twin.identification.side_angle.fused_angle`)
    turned off (``gyro_error_fused``) in every run where the runs' own
    estimates disagree: one gyro has one bias and one scale error, so two
    runs whose scales or biases differ by more than `AGREEMENT_Z` standard
    errors (their 95 % half-widths over 1.96, combined) and by more than
    `AGREEMENT_SHARE` of the larger show a difference between the angle and
    the integrated reading that is not a gyro error.

    A gyro on a flexible payload reads the payload's rate: its integral is
    the motor side's angle plus the deflection, which a cosine makes
    proportional to the angle, and the regression reads that as a scale
    error that changes with the run's frequency. Reference resonance axis
    450: 8.4 % on train1, 0.5 % on train2, 5.9 % held out (the reference
    gyro has none), the reading corrected by it moved the fused angle by up
    to 19 resolver steps, and the truth stood at 44 noise floors; without
    the correction 4.5 (docs/identification.md "Stop 80"). Runs the
    regression cannot read (too short, the angle does not move) are left
    out of the comparison; with fewer than two left, nothing changes.
    """
    estimates = []
    for d in runs:
        try:
            estimates.append(gyro_error_estimate([d]))
        except ParameterError:
            continue
    if len(estimates) < 2 or _agree(estimates):
        return list(runs)
    return [replace(d, gyro_error_fused=False) for d in runs]


def fusion_note(runs: Sequence[MeasuredData]) -> list[str]:
    """A report line where `one_gyro_error` turned the fusion's correction
    off, else none."""
    if not runs or runs[0].gyro_error_fused:
        return []
    return [
        "gyro error: the runs' estimates against the angle disagree (not one gyro's bias and "
        "scale; a payload's deflection reads so): the angle fusion leaves the reading as read"
    ]


def fusion_json(runs: Sequence[MeasuredData]) -> dict:
    """What `fusion_note` says, for the JSON summaries of ``identify`` and
    ``diagnose``: whether the angle fusion may correct the gyro reading by
    its estimated error (`one_gyro_error` sets ``gyro_error_fused`` on all
    runs together), and the note's sentence or None."""
    note = fusion_note(runs)
    return {
        "angle_fusion_corrects_gyro_error": all(d.gyro_error_fused for d in runs),
        "angle_fusion_note": note[0] if note else None,
    }


def _agree(estimates: Sequence[GyroError]) -> bool:
    """Whether every pair of estimates agrees in scale and in bias: within
    `AGREEMENT_Z` combined standard errors or `AGREEMENT_SHARE` of the
    larger estimate."""
    for i, a in enumerate(estimates):
        for b in estimates[i + 1 :]:
            for va, vb, wa, wb in (
                (a.scale, b.scale, a.scale_ci95, b.scale_ci95),
                (a.bias_rad_s, b.bias_rad_s, a.bias_ci95, b.bias_ci95),
            ):
                apart = abs(va - vb)
                if apart > AGREEMENT_Z * np.hypot(wa, wb) / _Z95 and apart > AGREEMENT_SHARE * max(
                    abs(va), abs(vb)
                ):
                    return False
    return True


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
