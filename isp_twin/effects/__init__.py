"""Extra physical effects on an axis, beyond the paper's friction law.

An effect is a small object with up to three hooks, applied each sample by
both the fast axis model and the MuJoCo twin:

* ``command(u)``: the amplifier's view of the command [digits] (dead zone,
  saturation, transport delay);
* ``acceleration(angle, rate)``: an extra torque divided by the axis inertia
  [rad/s^2] (cogging, cable spring, unbalance, offset, LuGre, resonance).
  Torque/J is what rate data determine; the twin multiplies by its inertia;
* ``measure(rate)``: the gyro's view of the rate [rad/s] (bias, scale).

Parameters are SI; names carry the unit where not SI. One module per effect in
this package, its class listed in `EFFECTS` below (tests/test_effects.py
checks that none is missing); `isp_twin.diagnosis` tests them as candidates. Effects are
stateful only through ``reset()``-able attributes.
"""

from __future__ import annotations

from isp_twin.effects import (
    cable_spring,
    cogging,
    deadzone,
    input_delay,
    lugre,
    resonance,
    saturation,
    sensor_bias,
    torque_offset,
    unbalance,
)
from isp_twin.effects.base import Effect
from isp_twin.errors import ParameterError, nearest
from isp_twin.parameters import EffectSpec

__all__ = [
    "Effect",
    "EFFECTS",
    "register",
    "make_effect",
    "cable_spring",
    "cogging",
    "deadzone",
    "input_delay",
    "lugre",
    "resonance",
    "saturation",
    "sensor_bias",
    "torque_offset",
    "unbalance",
]

#: Effect name -> class: every effect this package ships, listed once here.
EFFECTS: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        cable_spring.CableSpring,
        cogging.Cogging,
        deadzone.Deadzone,
        input_delay.InputDelay,
        lugre.LuGre,
        resonance.Resonance,
        saturation.Saturation,
        sensor_bias.SensorBias,
        torque_offset.TorqueOffset,
        unbalance.Unbalance,
    )
}


def register(cls: type[Effect]) -> type[Effect]:
    """Add an effect class to `EFFECTS` (for effects defined outside this package)."""
    EFFECTS[cls.name] = cls
    return cls


def make_effect(spec: EffectSpec, dt: float = 1e-3) -> Effect:
    """Build the effect named in a parameter file."""
    try:
        cls = EFFECTS[spec.name]
    except KeyError:
        raise ParameterError(
            f"unknown effect '{spec.name}'{nearest(spec.name, EFFECTS)}; "
            f"known: {', '.join(sorted(EFFECTS))}"
        ) from None
    return cls(spec.params, dt)
