"""A constant torque on the axis (amplifier offset, unbalance at a fixed attitude)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect


class TorqueOffset(Effect):
    """A constant torque on the axis: ``accel = accel_rad_s2`` (torque / J).

    Parameters: ``accel_rad_s2`` [rad/s^2].
    """

    name = "torque_offset"
    param_names = ("accel_rad_s2",)
    #: Plausible range of each parameter (fit bounds) [SI].
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"accel_rad_s2": 0.0}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"accel_rad_s2": (-200.0, 200.0)}
    # Exactly equivalent to shifting Ts and Tc of the + regimes down and of
    # the - regimes up (Eq. 5 has them per direction): only the local refit
    # from the current friction values makes it identifiable (the damped
    # Gauss-Newton step moves along that degenerate direction as little as
    # it can); see docs/diagnosis.md.

    acceleration_uses_rate = False

    def acceleration(self, angle, rate):
        return self.params["accel_rad_s2"] + 0.0 * np.asarray(angle)

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """Start values from the residual: the mean torque it implies."""
        moving = ctx.moving
        acc = float(np.mean(ctx.accel[moving])) if moving.any() else 0.0
        return [{"accel_rad_s2": acc}]
