"""The motor side's rate of a two-mass axis, for the equation-error start.

On a two-mass axis (a held `resonance` with ``payload_fraction`` f > 0) the
gyro sits on the payload and the resolver on the motor. Friction, the
viscous torque and the stick test act on the motor side's rate ``w1``, but
the gyro reads the payload's, which rings against it at the mode's
frequency after every breakaway and stop. Read from the gyro, the start's
rows took the ringing for friction and its sign changes for stops: on
reference resonance seeds 30, 38 and 43 it put the gain and Coulomb levels
80-100 % off (median over regimes), and `identify` with the *true* mode held
ended at 30-800 noise floors from there (docs/identification.md, "Stop 31").

The mode is known where it is held, so the motor side is estimated from
both sensors by a linear smoother (`motor_side_rates`): a steady-state
Kalman filter and Rauch-Tung-Striebel smoother over the centre of mass's
angle, rate and acceleration and the mode,
``x = (Theta, w, w', y, y', theta_g(k-1))``, the acceleration a random walk
(the unknown drive and friction: steady between breakaways and stops, so a
white acceleration instead left 2-3x the error on reference seeds 30, 33
and 38). The measurements are the resolver, ``Theta - r y`` at the
sample (r = f/(1 - f)), and the gyro averaged over the sample, the change
of its angle ``Theta + c y`` over the sample divided by the period.
Neither sensor alone will do: the resolver's difference quotient carries
its quantization (0.25-2 deg/s on those seeds), and inverting the mode from
the gyro alone amplifies its noise by ``(1 + r) / (2 zeta wn)`` per unit of
rate change.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm, solve_discrete_are

from isp_twin.identification.cost import rate_noise
from isp_twin.identification.measured import MeasuredData
from isp_twin.model.parameters import EffectSpec

__all__ = ["MotorSide", "payload_mode", "motor_side_rates"]

#: The effect that makes an axis two-mass where its payload fraction is > 0.
_PAYLOAD = "resonance"


@dataclass(frozen=True)
class MotorSide:
    """A run's rates behind a two-mass axis's sensors, shapes (N,), at the samples.

    Attributes:
        motor: the motor side's rate w1 [rad/s].
        centre: the centre-of-mass rate w [rad/s] (its change over a
            sample is the axis's total torque over J).
        motor_sd: the smoother's standard deviation of `motor` [rad/s].
    """

    motor: np.ndarray
    centre: np.ndarray
    motor_sd: float


def payload_mode(effects: Sequence[EffectSpec]) -> EffectSpec | None:
    """The held two-mass payload among `effects` (a `resonance` with a
    payload fraction above 0), or None."""
    for e in effects:
        if e.name == _PAYLOAD and float(e.params.get("payload_fraction", 0.0)) > 0.0:
            return e
    return None


def motor_side_rates(d: MeasuredData, mode: EffectSpec) -> MotorSide:
    """The motor side's and the centre of mass's rates of run `d` under the
    two-mass `mode` (module doc).

    The resolver's angle is ``d.resolver`` where the run carries the fused
    angle, else ``d.angle``; its noise is its quantization step (the
    smallest change it reads) over sqrt(12); the gyro's is `rate_noise`.
    The jerk's intensity is the gyro's mean squared second difference over
    the period cubed, which the ringing makes generous: the smoother then
    follows the sensors rather than its random walk.
    """
    theta = np.asarray(d.angle if d.resolver is None else d.resolver, dtype=float)
    gyro = np.asarray(d.omega, dtype=float)
    p = mode.params
    f = float(p["payload_fraction"])
    r, c = f / (1.0 - f), float(p["coupling"])
    step = np.abs(np.diff(theta))
    step = step[step > 0.0]
    lsb = float(np.min(step)) if step.size else 1e-6
    q = max(float(np.mean(np.diff(gyro, 2) ** 2)) / d.dt**3, 1e-12)
    big_f, big_q = _transition(float(p["freq_hz"]), float(p["damping_ratio"]), c, q, d.dt)
    h = np.array([[1.0, 0.0, 0.0, -r, 0.0, 0.0], [1.0, 0.0, 0.0, c, 0.0, -1.0]])
    h[1] /= d.dt
    noise = np.diag([lsb * lsb / 12.0, max(rate_noise([d]), 1e-9) ** 2])
    z = np.column_stack([theta, gyro])
    x0 = np.array([theta[0], gyro[0], 0.0, 0.0, 0.0, theta[0] - gyro[0] * d.dt])
    motor = np.array([0.0, 1.0, 0.0, 0.0, -r, 0.0])
    states, sd = _smoothed(big_f, big_q, h, noise, z, x0, motor)
    return MotorSide(states @ motor, states[:, 1], sd)


def _transition(freq_hz: float, zeta: float, c: float, q: float, dt: float):
    """The augmented state's transition (6, 6) and process noise (6, 6) over
    one sample (Van Loan's matrix exponential of the continuous model)."""
    wn = 2.0 * np.pi * freq_hz
    a = np.zeros((5, 5))  # (Theta, w, w', y, y')
    a[0, 1] = a[1, 2] = a[3, 4] = 1.0
    a[4, 2], a[4, 3], a[4, 4] = -1.0, -wn * wn, -2.0 * zeta * wn
    g = np.array([0.0, 0.0, 1.0, 0.0, 0.0])  # white jerk
    m = np.zeros((10, 10))
    m[:5, :5], m[:5, 5:], m[5:, 5:] = -a, q * np.outer(g, g), a.T
    e = expm(m * dt)
    ad = e[5:, 5:].T
    big_f = np.zeros((6, 6))
    big_f[:5, :5] = ad
    big_f[5, 0], big_f[5, 3] = 1.0, c  # the gyro's angle at the sample just ended
    big_q = np.zeros((6, 6))
    big_q[:5, :5] = ad @ e[:5, 5:]
    return big_f, 0.5 * (big_q + big_q.T)


def _smoothed(big_f, big_q, h, noise, z, x0, out_row) -> tuple[np.ndarray, float]:
    """Steady-state Kalman filter and Rauch-Tung-Striebel smoother: the
    smoothed states (N, 6) and the standard deviation of ``out_row @ x``."""
    n = big_f.shape[0]
    pp = solve_discrete_are(big_f.T, h.T, big_q, noise)
    gain = pp @ h.T @ np.linalg.inv(h @ pp @ h.T + noise)
    pf = (np.eye(n) - gain @ h) @ pp
    back = pf @ big_f.T @ np.linalg.inv(pp)
    # The smoothed covariance's backward recursion, run to its fixed point
    # (the Lyapunov solver is ill-conditioned: the angle is an integrator).
    ps = pf
    for _ in range(z.shape[0]):
        nxt = pf + back @ (ps - pp) @ back.T
        done = np.allclose(nxt, ps, rtol=1e-6, atol=0.0)
        ps = nxt
        if done:
            break
    ahead = (np.eye(n) - gain @ h) @ big_f
    kz = z @ gain.T
    filt = np.empty((z.shape[0], n))
    x = x0 + gain @ (z[0] - h @ x0)
    filt[0] = x
    for k in range(1, z.shape[0]):
        x = kz[k] + ahead @ x
        filt[k] = x
    out = filt.copy()
    for k in range(z.shape[0] - 2, -1, -1):
        out[k] = filt[k] + back @ (out[k + 1] - big_f @ filt[k])
    return out, float(np.sqrt(max(out_row @ ps @ out_row, 0.0)))
