"""Mass unbalance: gravity on an off-axis centre of mass, a torque sine of the angle."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect


class Unbalance(Effect):
    """``accel = amplitude_rad_s2 * sin(angle + phase_rad)``.

    Parameters: ``amplitude_rad_s2`` [rad/s^2] (m*g*r / J), ``phase_rad``
    [rad] (where the centre of mass points at angle 0, gravity direction
    included).
    """

    name = "unbalance"
    param_names = ("amplitude_rad_s2", "phase_rad")
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"amplitude_rad_s2": 0.0, "phase_rad": 0.0}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "amplitude_rad_s2": (0.0, 500.0),
        "phase_rad": (-2.0 * np.pi, 2.0 * np.pi),
    }

    acceleration_uses_rate = False

    def acceleration(self, angle, rate):
        p = self.params
        return p["amplitude_rad_s2"] * np.sin(angle + p["phase_rad"])

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """Start values: least squares of the residual's acceleration on sin/cos(angle)."""
        angle, acc = ctx.angle[ctx.moving], ctx.accel[ctx.moving]
        if angle.size < 3:
            return [{"amplitude_rad_s2": 0.0, "phase_rad": 0.0}]
        basis = np.stack([np.sin(angle), np.cos(angle)], axis=1)
        (cs, sn), *_ = np.linalg.lstsq(basis, acc, rcond=None)
        # A sin(y + phi) = A cos(phi) sin(y) + A sin(phi) cos(y)
        return [
            {"amplitude_rad_s2": float(np.hypot(cs, sn)), "phase_rad": float(np.arctan2(sn, cs))}
        ]
