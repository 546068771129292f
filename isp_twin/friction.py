"""The improved Stribeck friction law (paper Eq. 5).

One implementation for the MuJoCo twin, the fast discrete axis model and
identification. It is unit-agnostic: torques, rates and the curve factor only
have to be consistent (the twin passes N·m, rad/s, s/rad; the axis model passes
the rate form of Eq. 6, i.e. torques already multiplied by b).

Regimes follow the paper's Fig. 3: the side of the angle (R: angle > 0,
L: angle <= 0) times the direction of motion (+/-). The direction is the sign
of the rate while moving and, at rest, the sign of the drive torque (the
stiction branch of Eq. 5). `Ts` and `Tc` are magnitudes for both directions:
the paper's condition "T_s^- < T_m" reads as "-T_s^- < T_m".

All functions broadcast: parameters have shape (..., 4) (regimes last, in
`REGIMES` order R+, R-, L+, L-), state arrays have the leading shape.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "regime_index",
    "take_regime",
    "stribeck_magnitude",
    "sliding_friction",
    "stiction_friction",
    "friction_torque",
]


def regime_index(angle, direction) -> np.ndarray:
    """Index into `REGIMES` for each sample.

    Args:
        angle: gimbal angle relative to its parent (any angle unit) .
        direction: sign of motion (rate while moving, drive torque at rest);
            zero counts as positive.

    Returns:
        int array: 0 = R+, 1 = R-, 2 = L+, 3 = L-.
    """
    left = np.asarray(angle) <= 0.0
    negative = np.asarray(direction) < 0.0
    return 2 * left.astype(np.intp) + negative.astype(np.intp)


def take_regime(param: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Select ``param[..., index]`` element-wise (param shape (..., 4))."""
    param = np.asarray(param)
    index = np.asarray(index)
    shape = np.broadcast_shapes(param.shape[:-1], index.shape)
    param = np.broadcast_to(param, shape + (4,))
    return np.take_along_axis(param, np.broadcast_to(index, shape)[..., None], axis=-1)[..., 0]


def stribeck_magnitude(speed, static, coulomb, alpha):
    """Stribeck curve of Eq. 3: ``Tc + (Ts - Tc) * exp(-alpha * speed)`` for speed >= 0."""
    return coulomb + (static - coulomb) * np.exp(-alpha * speed)


def sliding_friction(rate, static, coulomb, alpha):
    """Eq. 5 for a moving axis: ``sgn(rate) * stribeck(|rate|)`` (regime already selected)."""
    return np.sign(rate) * stribeck_magnitude(np.abs(rate), static, coulomb, alpha)


def stiction_friction(drive, static):
    """Eq. 5 for an axis at rest: the friction equals the drive up to the breakaway ``static``.

    Returns the friction torque (same sign as the drive); the axis breaks away
    where ``|drive| > static`` and then the net torque is ``drive - friction``.
    """
    return np.clip(drive, -static, static)


def friction_torque(rate, drive, angle, static, coulomb, alpha):
    """The complete law of Eq. 5: T_f(omega_2, T_m, Y), regime chosen inside.

    Args:
        rate: relative rate omega_2; exactly 0 means "at rest".
        drive: motor torque T_m.
        angle: angle Y (only its sign matters).
        static, coulomb, alpha: per-regime parameters, shape (..., 4).

    Returns:
        (torque, regime): friction torque opposing the motion and the regime index.
    """
    rate = np.asarray(rate, dtype=float)
    drive = np.asarray(drive, dtype=float)
    moving = rate != 0.0
    direction = np.where(moving, rate, drive)
    regime = regime_index(angle, direction)
    ts = take_regime(static, regime)
    tc = take_regime(coulomb, regime)
    al = take_regime(alpha, regime)
    torque = np.where(moving, sliding_friction(rate, ts, tc, al), stiction_friction(drive, ts))
    return torque, regime
