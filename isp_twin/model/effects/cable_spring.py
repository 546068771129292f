"""A cable or wire bundle: a torque linear in angle, with an offset."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect


class CableSpring(Effect):
    """``accel = offset_rad_s2 - stiffness_1_s2 * angle`` (torque / J).

    Parameters: ``stiffness_1_s2`` [rad/s^2 per rad] (spring constant / J;
    positive pulls back to the neutral angle), ``offset_rad_s2`` [rad/s^2]
    (the pull at angle 0: the cable's neutral angle is offset / stiffness).
    """

    name = "cable_spring"
    param_names = ("stiffness_1_s2", "offset_rad_s2")
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"stiffness_1_s2": 0.0, "offset_rad_s2": 0.0}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "stiffness_1_s2": (-5000.0, 5000.0),
        "offset_rad_s2": (-200.0, 200.0),
    }
    #: A constant torque is exactly equivalent to shifting Ts and Tc of the
    #: + regimes down and of the - regimes up (Eq. 5 has them per direction),
    #: so rate data cannot separate the offset from friction: it keeps the
    #: value the residual of the current model shows (`guesses`).
    frozen: ClassVar[tuple[str, ...]] = ("offset_rad_s2",)

    acceleration_uses_rate = False

    def acceleration(self, angle, rate):
        p = self.params
        return p["offset_rad_s2"] - p["stiffness_1_s2"] * angle

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """Start values: a straight line through the residual's acceleration vs angle."""
        angle, acc = ctx.angle[ctx.moving], ctx.accel[ctx.moving]
        if angle.size < 3:
            return [{"stiffness_1_s2": 0.0, "offset_rad_s2": 0.0}]
        slope, offset = np.polyfit(angle, acc, 1)
        return [{"stiffness_1_s2": float(-slope), "offset_rad_s2": float(offset)}]
