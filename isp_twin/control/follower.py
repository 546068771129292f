"""The outer-gimbal follower (paper Sect. 4.2).

"The angular position output of the inner gimbal is the reference position
input of the outer gimbal": each outer gimbal turns so that the inner gimbal's
angle relative to it returns to zero, keeping the inner gimbals well inside
their ±4 deg stops. The follow error is therefore the inner gimbal's resolver
angle. The loop is a PID on that error, with the derivative taken on the
outer gimbal's own measured rate (no derivative kick), bounded like the
inner loops.
"""

from __future__ import annotations

import math

__all__ = ["OuterFollower"]


class OuterFollower:
    """PID position follower of one outer gimbal.

    Args:
        kp: [digits per rad] of follow error.
        ki: [digits per rad, per sample].
        kd: [digits per rad/s] of the outer gimbal's rate.
        limit: command bound [digits].
    """

    def __init__(self, kp: float, ki: float, kd: float, limit: float):
        for name, v in (("kp", kp), ("ki", ki), ("kd", kd)):
            if not (v >= 0 and math.isfinite(v)):
                raise ValueError(f"follower {name} must be finite and >= 0, got {v}")
        if not limit > 0:
            raise ValueError(f"follower limit must be > 0, got {limit}")
        self.kp, self.ki, self.kd, self.limit = float(kp), float(ki), float(kd), float(limit)
        self.reset()

    def reset(self) -> None:
        """Zero the integrator."""
        self.integral = 0.0

    def step(self, error: float, rate: float) -> float:
        """The outer command [digits] for the follow error [rad] and outer rate [rad/s]."""
        s = self.integral + error
        u = self.kp * error + self.ki * s - self.kd * rate
        lim = self.limit
        if abs(u) > lim:
            if u * error <= 0.0:
                self.integral = s
            return lim if u > 0 else -lim
        self.integral = s
        return u
