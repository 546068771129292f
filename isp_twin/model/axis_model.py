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
* Extra effects (`isp_twin.model.effects`), applied per sample as in the twin: the
  command passes through each ``command`` hook, the ``acceleration`` hooks
  (at the angle that selects the half-plane and the rate of the previous
  sample) add ``accel*T`` to the drive, and the rate is reported through
  the ``measure`` hooks (gyro errors, structural modes). ``accel*T`` is what
  the twin's explicit-Euler step gives a torque J·accel (docs/axis_model.md,
  section 5), so an effect's torque/J means the same in both engines.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from isp_twin.model.effects import Effect
from isp_twin.model.friction import (
    regime_index,
    sliding_friction,
    stiction_friction,
    stribeck_magnitude,
)
from isp_twin.model.parameters import RateParams
from isp_twin.vocabulary import SIDE_R, check_side

__all__ = ["AxisResponse", "simulate", "steady_rate"]


@dataclass(frozen=True)
class AxisResponse:
    """Simulated open-loop response.

    Attributes:
        omega: relative rate [rad/s], shape (P, N) (or (N,) for one set).
        angle: angle [rad], same shape.
        regime: regime index used for the step into each sample, same shape.
        omega_true: the axis's own rate [rad/s] when measurement effects make
            ``omega`` (what the gyro reads) differ from it; else None.
    """

    omega: np.ndarray
    angle: np.ndarray
    regime: np.ndarray
    omega_true: np.ndarray | None = None

    def mapped(self, f: Callable[[np.ndarray], np.ndarray]) -> AxisResponse:
        """The response with ``f`` applied to each array (a reshape, a row)."""
        arrays = (self.omega, self.angle, self.regime, self.omega_true)
        return AxisResponse(*(None if a is None else f(a) for a in arrays))


def simulate(
    params: RateParams,
    u: np.ndarray,
    dt: float,
    omega0: float = 0.0,
    angle0: float = 0.0,
    angle_measured: np.ndarray | None = None,
    angle_limit: float | None = None,
    extra_rate: np.ndarray | None = None,
    effects: Sequence[Effect] = (),
    side: int | None = None,
) -> AxisResponse:
    """Simulate Eq. 6 for a batch of parameter sets.

    Args:
        params: rate-form parameters, arrays (4,) or (P, 4).
        u: command [digits], shape (N,), or (P, N): one command per set
            (several runs simulated side by side as rows of one batch).
        dt: sample period T [s].
        omega0: rate at sample 0 [rad/s] (sample 0 is given, not simulated);
            a float or shape (P,).
        angle0: angle at sample 0 [rad]; a float or shape (P,).
        angle_measured: if given, shape (N,) or (P, N), the measured angle
            [rad] used to pick the half-plane (teacher forcing), instead of
            the simulated one.
        angle_limit: symmetric hard stop [rad]; None for none.
        extra_rate: an additional drive in rate form [rad/s per sample], shape
            (N,) or (P, N), added to b*Ke*u (extra effects enter here).
        effects: extra effects (reset here, then stepped); their parameters
            are floats or arrays of shape (P,) matching the batch
            (`isp_twin.model.effects.batched.make_batched`).
        side: fix the half-plane for the regime choice (`SIDE_R` or
            `SIDE_L`) whatever the angle (a freely spinning motor, where the paper's
            split means nothing); the effects still see the angle.

    Returns:
        `AxisResponse`; shapes (N,) for unbatched params, else (P, N).
    """
    single = np.ndim(params.pole) == 1
    pole, gain, static, coulomb, alpha = (
        np.atleast_2d(np.asarray(x, dtype=float))
        for x in (params.pole, params.gain, params.static, params.coulomb, params.alpha)
    )
    u = np.asarray(u, dtype=float)
    per_row_u = u.ndim == 2
    if per_row_u:
        single = False
    n_sets = max(p.shape[0] for p in (pole, gain, static, coulomb, alpha))
    n_sets = max(n_sets, u.shape[0] if per_row_u else 1, np.size(omega0), np.size(angle0))
    pole, gain, static, coulomb, alpha = (
        np.broadcast_to(p, (n_sets, 4)) for p in (pole, gain, static, coulomb, alpha)
    )
    if per_row_u:
        u = np.broadcast_to(u, (n_sets, u.shape[1])).T  # (N, P): one row per step
    n = u.shape[0]
    if angle_measured is not None:
        angle_measured = np.asarray(angle_measured, dtype=float)
        if angle_measured.ndim == 2:
            angle_measured = np.broadcast_to(angle_measured, (n_sets, n)).T
    rows = np.arange(n_sets)
    w = np.broadcast_to(np.asarray(omega0, dtype=float), (n_sets,)).copy()
    y = np.broadcast_to(np.asarray(angle0, dtype=float), (n_sets,)).copy()
    # Time-major buffers: each step writes one contiguous row.
    omega_t = np.empty((n, n_sets))
    angle_t = np.empty((n, n_sets))
    regime_t = np.zeros((n, n_sets), dtype=np.intp)
    omega_t[0] = w
    angle_t[0] = y
    extra = None if extra_rate is None else np.broadcast_to(extra_rate, (n_sets, n))
    commands = [e for e in effects if type(e).command is not Effect.command]
    torques = [e for e in effects if type(e).acceleration is not Effect.acceleration]
    sensors = [e for e in effects if type(e).measure is not Effect.measure]
    for e in effects:
        e.reset()
    measured = None
    if sensors:
        measured = np.empty((n, n_sets))
        m = w
        for e in sensors:
            m = e.measure(m)
        measured[0] = m
    # One gather per step: row * regimes + regime indexes the (P*regimes,
    # fields) table, its columns in the order stacked here.
    columns = (pole, gain, static, coulomb, alpha)
    table = np.stack(columns, axis=-1).reshape(-1, len(columns))
    gain_flat = table[:, 1]
    base = rows * pole.shape[-1]
    # A fixed side enters the regime choice as an angle on that side.
    fixed_side = None if check_side(side) is None else (1.0 if side == SIDE_R else -1.0)
    for k in range(1, n):
        side_angle = y if angle_measured is None else angle_measured[k - 1]
        uk = u[k - 1]
        for e in commands:
            uk = e.command(uk)
        more = None if extra is None else extra[:, k - 1]
        acc = sum(e.acceleration(side_angle, w) for e in torques) if torques else None
        side_angle = side_angle if fixed_side is None else fixed_side
        moving = w != 0.0
        # Moving, the rate's sign picks the regime. At rest Eq. 5's T_m is the
        # motor's: the command's sign picks the gain, and the total drive
        # (motor + effects) must exceed the breakaway Ts of the direction it
        # pushes, as the twin's direction-dependent stiction constraint does.
        drive = gain_flat[base + regime_index(side_angle, np.where(moving, w, uk))] * uk
        if more is not None:
            drive = drive + more
        if acc is not None:
            drive = drive + acc * dt
        idx = base + regime_index(side_angle, np.where(moving, w, drive))
        a, _, ts, tc, al = table[idx].T
        w_move = a * w + drive - sliding_friction(w, ts, tc, al)
        # Friction cannot reverse the motion: a sign change ends at rest.
        w_move = np.where(w_move * w > 0.0, w_move, 0.0)
        # At rest the net drive is what exceeds the breakaway (0 below it).
        w_rest = drive - stiction_friction(drive, ts)
        w = np.where(moving, w_move, w_rest)
        y = y + dt * w
        if angle_limit is not None:
            hit = np.abs(y) >= angle_limit
            # At the stop only a motion away from it survives.
            w = np.where(hit & (np.sign(w) == np.sign(y)), 0.0, w)
            y = np.clip(y, -angle_limit, angle_limit)
        omega_t[k] = w
        angle_t[k] = y
        regime_t[k] = idx - base
        if sensors:
            m = w
            for e in sensors:
                m = e.measure(m)
            measured[k] = m
    omega, angle, regime = omega_t.T, angle_t.T, regime_t.T
    if measured is not None:
        measured = measured.T
    true = None
    if measured is not None:
        omega, true = measured, omega
    if single:
        return AxisResponse(omega[0], angle[0], regime[0], None if true is None else true[0])
    return AxisResponse(omega, angle, regime, true)


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
