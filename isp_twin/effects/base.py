"""The effect interface: what an effect may hook into, and its parameter check.

Every effect module subclasses `Effect`; the package (`isp_twin.effects`)
collects them into the registry `EFFECTS`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

from isp_twin.errors import ParameterError, nearest

__all__ = ["Effect"]


class Effect:
    """Base class: no effect. Subclasses set `name`, `param_names` and override hooks."""

    name: ClassVar[str] = "none"
    param_names: ClassVar[tuple[str, ...]] = ()
    #: False where `acceleration` depends on the angle alone (no rate, no
    #: state): the sub-stepped model then evaluates it before the run
    #: instead of once per sample (`isp_twin.substep_model`).
    acceleration_uses_rate: ClassVar[bool] = True

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
