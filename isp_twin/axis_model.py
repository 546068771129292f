"""The fast discrete-time axis model of Eq. 6, with the four friction regimes.

``omega[k] = a*omega[k-1] + b*Ke*u[k-1] - b*T_f(omega[k-1], T_m, Y[k-1])``

in the rate form of `RateParams` (rad/s, per sample). It evaluates a whole
batch of parameter sets at once (identification calls it thousands of times):
parameters of shape (P, 4) give responses of shape (P, N).

Discrete stick-slip, the decisions Eq. 6 leaves open:

* At rest (omega exactly 0) the stiction branch of Eq. 5 applies: the axis stays
  at rest while |b*Ke*u| <= b*Ts of the regime the drive points to, otherwise
  ``omega = b*Ke*u - sgn(u)*b*Ts`` (Eq. 6 with omega[k-1] = 0).
* Moving, a step that would change the sign of the rate ends at rest instead
  (friction cannot reverse the motion): reversals pass through a sample of
  stick and never chatter.
* The angle integrates the rate, ``Y[k] = Y[k-1] + T*omega[k]`` (the same
  semi-implicit rule as MuJoCo), unless a measured angle is given, which then
  selects the half-plane.
* Optional hard stops (the inner gimbals' ±4 deg): reaching one stops the axis,
  as the joint limit does in the twin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isp_twin.friction import regime_index, stribeck_magnitude
from isp_twin.parameters import RateParams

__all__ = ["AxisResponse", "simulate", "steady_rate"]


@dataclass(frozen=True)
class AxisResponse:
    """Simulated open-loop response.

    Attributes:
        omega: relative rate [rad/s], shape (P, N) (or (N,) for one set).
        angle: angle [rad], same shape.
        regime: regime index used for the step into each sample, same shape.
    """

    omega: np.ndarray
    angle: np.ndarray
    regime: np.ndarray


def simulate(
    params: RateParams,
    u: np.ndarray,
    dt: float,
    omega0: float = 0.0,
    angle0: float = 0.0,
    angle_measured: np.ndarray | None = None,
    angle_limit: float | None = None,
    extra_rate: np.ndarray | None = None,
) -> AxisResponse:
    """Simulate Eq. 6 for a batch of parameter sets.

    Args:
        params: rate-form parameters, arrays (4,) or (P, 4).
        u: command [digits], shape (N,).
        dt: sample period T [s].
        omega0: rate at sample 0 [rad/s] (sample 0 is given, not simulated).
        angle0: angle at sample 0 [rad].
        angle_measured: if given, shape (N,), the measured angle [rad] used to
            pick the half-plane (teacher forcing), instead of the simulated one.
        angle_limit: symmetric hard stop [rad]; None for none.
        extra_rate: an additional drive in rate form [rad/s per sample], shape
            (N,) or (P, N), added to b*Ke*u (extra effects enter here).

    Returns:
        `AxisResponse`; shapes (N,) for unbatched params, else (P, N).
    """
    single = np.ndim(params.pole) == 1
    pole, gain, static, coulomb, alpha = (
        np.atleast_2d(np.asarray(x, dtype=float))
        for x in (params.pole, params.gain, params.static, params.coulomb, params.alpha)
    )
    n_sets = max(p.shape[0] for p in (pole, gain, static, coulomb, alpha))
    pole, gain, static, coulomb, alpha = (
        np.broadcast_to(p, (n_sets, 4)) for p in (pole, gain, static, coulomb, alpha)
    )
    u = np.asarray(u, dtype=float)
    n = u.shape[0]
    rows = np.arange(n_sets)
    omega = np.empty((n_sets, n))
    angle = np.empty((n_sets, n))
    regime = np.zeros((n_sets, n), dtype=np.intp)
    w = np.full(n_sets, float(omega0))
    y = np.full(n_sets, float(angle0))
    omega[:, 0] = w
    angle[:, 0] = y
    extra = None if extra_rate is None else np.broadcast_to(extra_rate, (n_sets, n))
    for k in range(1, n):
        side_angle = y if angle_measured is None else angle_measured[k - 1]
        # At rest the drive's sign picks the direction; gains are positive, so
        # the + regime of the current side decides it (exact without extra_rate).
        side = regime_index(side_angle, 1.0)
        probe = gain[rows, side] * u[k - 1]
        if extra is not None:
            probe = probe + extra[:, k - 1]
        r = regime_index(side_angle, np.where(w != 0.0, w, probe))
        a = pole[rows, r]
        drive = gain[rows, r] * u[k - 1]
        if extra is not None:
            drive = drive + extra[:, k - 1]
        ts = static[rows, r]
        moving = w != 0.0
        slide = np.sign(w) * stribeck_magnitude(np.abs(w), ts, coulomb[rows, r], alpha[rows, r])
        w_move = a * w + drive - slide
        w_move = np.where(np.sign(w_move) == np.sign(w), w_move, 0.0)
        w_rest = np.where(np.abs(drive) > ts, drive - np.sign(drive) * ts, 0.0)
        w = np.where(moving, w_move, w_rest)
        y = y + dt * w
        if angle_limit is not None:
            hit = np.abs(y) >= angle_limit
            # At the stop only a motion away from it survives.
            w = np.where(hit & (np.sign(w) == np.sign(y)), 0.0, w)
            y = np.clip(y, -angle_limit, angle_limit)
        omega[:, k] = w
        angle[:, k] = y
        regime[:, k] = r
    if single:
        return AxisResponse(omega[0], angle[0], regime[0])
    return AxisResponse(omega, angle, regime)


def steady_rate(params: RateParams, u: float, regime: int) -> float:
    """Quasi-static sliding rate [rad/s] for a constant command in one regime.

    Solves ``(1 - a)*omega = b*Ke*u - b*Tf(omega)``; 0 when the command cannot
    overcome Coulomb friction. Used as an analytic check of `simulate`.
    """
    from scipy.optimize import brentq

    a = float(params.pole[regime])
    drive = float(params.gain[regime] * u)
    s, c, al = (float(x[regime]) for x in (params.static, params.coulomb, params.alpha))
    sign = np.sign(drive)

    def balance(w):
        return (1 - a) * w - (abs(drive) - stribeck_magnitude(w, s, c, al))

    if abs(drive) <= c:
        return 0.0
    hi = abs(drive) / (1 - a) + 1.0
    return float(sign * brentq(balance, 0.0, hi))
