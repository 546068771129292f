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
this package; `isp_twin.diagnosis` tests them as candidates. Effects are
stateful only through ``reset()``-able attributes.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

from isp_twin.errors import ParameterError, nearest
from isp_twin.parameters import EffectSpec

__all__ = ["Effect", "EFFECTS", "register", "make_effect"]

#: Effect name -> class; filled by `register`.
EFFECTS: dict[str, type[Effect]] = {}


class Effect:
    """Base class: no effect. Subclasses set `name`, `param_names` and override hooks."""

    name: ClassVar[str] = "none"
    param_names: ClassVar[tuple[str, ...]] = ()

    def __init__(self, params: Mapping[str, float], dt: float = 1e-3):
        missing = [p for p in self.param_names if p not in params]
        unknown = [p for p in params if p not in self.param_names]
        if missing or unknown:
            bad = (missing or unknown)[0]
            raise ParameterError(
                f"effect '{self.name}': {'missing' if missing else 'unknown'} parameter "
                f"'{bad}'{nearest(bad, self.param_names)}; expects {', '.join(self.param_names)}"
            )
        self.params = {k: float(params[k]) for k in self.param_names}
        self.dt = dt
        self.reset()

    def reset(self) -> None:
        """Clear internal state (delay lines, filter states)."""

    def command(self, u: float) -> float:
        return u

    def acceleration(self, angle: float, rate: float) -> float:
        return 0.0

    def measure(self, rate: float) -> float:
        return rate


def register(cls: type[Effect]) -> type[Effect]:
    """Class decorator adding an effect to `EFFECTS`."""
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


# Each module registers its effect on import (after the base class exists).
from isp_twin.effects import (  # noqa: E402
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

__all__ += [
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
