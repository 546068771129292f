"""The improved Stribeck friction law (paper Eq. 5).

One implementation for the MuJoCo twin, the fast discrete axis model and
identification. It is unit-agnostic: torques, rates and the curve factor only
have to be consistent (the twin passes N·m, rad/s, s/rad; the axis model passes
the rate form of Eq. 6, i.e. torques already multiplied by b).

Regimes follow the paper's Fig. 3: the side of the angle (R: angle > 0,
L: angle < 0) times the direction of motion (+/-). The direction is the sign
of the rate while moving and, at rest, the sign of the drive torque (the
stiction branch of Eq. 5). At the boundary, an angle of exactly 0 (an axis
at rest there, a resolver reading 0), the side is the one the motion enters:
R for a positive direction, L otherwise. Eq. 5 puts Y = 0 in L, but in
continuous time a positive motion from Y = 0 is at once in Y > 0, where the
R+ law holds: a drive between T_sL^+ and T_sR^+ stops again at 0+ (the
reference simulator, `isp_twin.reference.axis`, does exactly this). Only
the breakaway from exactly 0 differs from the literal reading; see
docs/axis_model.md, "The side at angle 0". `Ts` and `Tc` are magnitudes for both directions:
the paper's condition "T_s^- < T_m" reads as "-T_s^- < T_m".

The law is written once, as plain-float scalar functions (`side_of`,
`regime_of`, `stribeck`, `sliding`, `stiction`: the ``math`` module only) that
the per-step callers use as they are (the twin's step, the NFC) and that
`isp_twin.experiments.closed_loop_kernel` compiles with numba from this same source. The
array functions below them apply the same law to batches (the fast axis
model, identification); tests/test_friction.py checks that both forms agree
on every regime, at rest and moving.

The array functions broadcast: parameters have shape (..., 4) (regimes last,
in `REGIMES` order R+, R-, L+, L-), state arrays have the leading shape.
"""

from __future__ import annotations

import math

import numpy as np

# The side indices are the vocabulary's (numba reads them as constants).
from isp_twin.vocabulary import SIDE_L, SIDE_R

__all__ = [
    "SCALAR_LAW",
    "SIDE_R",
    "SIDE_L",
    "side_of",
    "regime_of",
    "stribeck",
    "sliding",
    "stiction",
    "regime_index",
    "take_regime",
    "stribeck_magnitude",
    "sliding_friction",
    "stiction_friction",
    "friction_torque",
]

#: The scalar form, one function per step of Eq. 5 (compiled by numba as they are).
SCALAR_LAW = ("side_of", "regime_of", "stribeck", "sliding", "stiction")

# ------------------------------------------------------------------ scalar form
# Plain floats and the math module only: numba compiles these unchanged, and
# the compiled closed loop must repeat the Python step bit for bit.


def side_of(angle: float, direction: float) -> int:
    """The side of the angle: `SIDE_R` (angle > 0) or `SIDE_L` (angle < 0).

    At angle 0 the side the motion in `direction` (as `regime_of`) enters:
    `SIDE_R` for a positive direction, `SIDE_L` for a negative or zero one.
    """
    if angle > 0.0 or (angle == 0.0 and direction > 0.0):
        return SIDE_R
    return SIDE_L


def regime_of(side: int, direction: float) -> int:
    """Index into `REGIMES` (0 = R+, 1 = R-, 2 = L+, 3 = L-).

    Args:
        side: `SIDE_R` or `SIDE_L` (`side_of` the angle and this direction).
        direction: sign of motion: the rate while moving, the drive torque at
            rest (the stiction branch of Eq. 5); zero counts as positive.
    """
    return 2 * side + (1 if direction < 0.0 else 0)


def stribeck(speed: float, static: float, coulomb: float, alpha: float) -> float:
    """Stribeck magnitude of Eq. 3/5: ``Tc + (Ts - Tc) * exp(-alpha * speed)``, speed >= 0."""
    return coulomb + (static - coulomb) * math.exp(-alpha * speed)


def sliding(rate: float, static: float, coulomb: float, alpha: float) -> float:
    """Eq. 5 for a moving axis (rate != 0): ``sgn(rate) * stribeck(|rate|)``."""
    magnitude = stribeck(abs(rate), static, coulomb, alpha)
    return magnitude if rate > 0.0 else -magnitude


def stiction(drive: float, static: float) -> float:
    """Eq. 5 for an axis at rest: the friction equals the drive up to the breakaway ``static``."""
    return static if drive > static else (-static if drive < -static else drive)


# ------------------------------------------------------------------- array form


def regime_index(angle, direction) -> np.ndarray:
    """Index into `REGIMES` for each sample.

    Args:
        angle: gimbal angle relative to its parent (any angle unit) .
        direction: sign of motion (rate while moving, drive torque at rest);
            zero counts as positive, except that at angle 0 only a positive
            direction is on the right (`side_of`).

    Returns:
        int array: 0 = R+, 1 = R-, 2 = L+, 3 = L-.
    """
    # The same test as `side_of` / `regime_of`, element-wise.
    angle = np.asarray(angle)
    direction = np.asarray(direction)
    left = (angle < 0.0) | ((angle == 0.0) & ~(direction > 0.0))
    negative = direction < 0.0
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
