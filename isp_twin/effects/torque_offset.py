"""A constant torque on the axis (amplifier offset, unbalance at a fixed attitude)."""

from __future__ import annotations

from isp_twin.effects import Effect, register


@register
class TorqueOffset(Effect):
    """A constant torque on the axis (unbalance at fixed attitude, amplifier offset)."""

    name = "torque_offset"
    param_names = ("accel_rad_s2",)

    def acceleration(self, angle: float, rate: float) -> float:
        return self.params["accel_rad_s2"]
