"""An amplifier saturation: the command is clipped at a limit."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect, elementwise_run


class Saturation(Effect):
    """``u_amp = clip(u, -limit_digits, limit_digits)``.

    Parameters: ``limit_digits`` [digits], > 0.
    """

    name = "saturation"
    param_names = ("limit_digits",)
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"limit_digits": float("inf")}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"limit_digits": (1.0, 1e6)}

    def command(self, u):
        lim = self.params["limit_digits"]
        return np.clip(u, -lim, lim)

    def command_run(self, u):
        """Without state: the whole run in one call."""
        return elementwise_run(self.command, u)

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """Limits at quantiles of |u| (a limit above every command changes nothing)."""
        mag = np.abs(np.asarray(ctx.u, dtype=float))
        qs = np.linspace(0.5, 0.995, 34)
        return [{"limit_digits": float(max(np.quantile(mag, q), 1.0))} for q in qs]
