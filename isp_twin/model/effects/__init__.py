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
checks that none is missing); `isp_twin.diagnosis` tests them as candidates,
in the registry's order. Every caller finds a class with `effect_class` (an
unknown name is one error listing the known ones) and checks parameters with
`Effect.check_params`. Effects are stateful only through ``reset()``-able
attributes.
"""

from __future__ import annotations

from isp_twin.errors import ParameterError, nearest
from isp_twin.model.effects import (
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
from isp_twin.model.effects.base import Effect
from isp_twin.model.parameters import EffectSpec

__all__ = [
    "Effect",
    "EFFECTS",
    "register",
    "effect_class",
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

#: Effect name -> class: every effect this package ships, listed once here, in
#: the order `diagnose` tests and reports them (`isp_twin.diagnosis.prepared_runs.LIBRARY`).
EFFECTS: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        cogging.Cogging,
        cable_spring.CableSpring,
        unbalance.Unbalance,
        torque_offset.TorqueOffset,
        input_delay.InputDelay,
        deadzone.Deadzone,
        saturation.Saturation,
        sensor_bias.SensorBias,
        lugre.LuGre,
        resonance.Resonance,
    )
}


def register(cls: type[Effect]) -> type[Effect]:
    """Add an effect class to `EFFECTS` (for effects defined outside this package)."""
    EFFECTS[cls.name] = cls
    return cls


def effect_class(name: str, what: str = "effect") -> type[Effect]:
    """The registered class of the effect called `name`.

    Args:
        name: effect name, e.g. ``cogging``.
        what: what the caller calls it in the message (``candidate effect``).

    Raises:
        ParameterError: unknown name; the message suggests the nearest and
            lists the known ones.
    """
    try:
        return EFFECTS[name]
    except KeyError:
        raise ParameterError(
            f"unknown {what} '{name}'{nearest(name, EFFECTS)}; known: {', '.join(sorted(EFFECTS))}"
        ) from None


def make_effect(spec: EffectSpec, dt: float = 1e-3) -> Effect:
    """Build the effect named in a parameter file."""
    return effect_class(spec.name)(spec.params, dt)
