"""An amplifier dead zone: small commands produce no torque."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect, elementwise_run


class Deadzone(Effect):
    """``u_amp = sign(u) * max(|u| - width_digits, 0)`` (symmetric dead band).

    Parameters: ``width_digits`` [digits], >= 0.
    """

    name = "deadzone"
    param_names = ("width_digits",)
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"width_digits": 0.0}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"width_digits": (0.0, 5000.0)}

    def command(self, u):
        return np.sign(u) * np.maximum(np.abs(u) - self.params["width_digits"], 0.0)

    def command_run(self, u):
        """Without state: the whole run in one call."""
        return elementwise_run(self.command, u)

    #: The narrowest width tried and reported, a fraction of the largest command.
    SMALLEST = 0.005

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """A grid of widths, `SMALLEST` (0.5 %) to 40 % of the largest command (geometric)."""
        top = float(np.max(np.abs(ctx.u))) or 1.0
        return [{"width_digits": f * top} for f in np.geomspace(cls.SMALLEST, 0.4, 40)]

    #: Beyond the band the drive loses the motor gain times the width, as
    #: while sliding it loses the Coulomb level: on cosine runs a wider band
    #: under lower levels fits alike (`Effect.trade_parameter`).
    trade_parameter = "width_digits"

    #: Refined starts (`refined_starts`): these fractions of the widest dead
    #: zone the base's friction levels can carry.
    REFINED_SHARES = (0.2, 0.4, 0.6, 0.8)

    @classmethod
    def refined_starts(cls, ctx) -> list[dict[str, float]]:
        """Widths at `REFINED_SHARES` of the base's Coulomb level in digits
        (`ResidualContext.coulomb_digits`; none where it is not known), each
        refined with the friction levels lowered by the motor gain times
        the width (`drive_taken_digits`).

        On the cosine runs a drive beyond the band loses the gain times the
        width, as it loses the Coulomb friction while sliding: the base
        carries the dead zone in its levels, and a width guessed at those
        levels fits no better, however wide the band. Reference dead zone
        334 (covered design, a 126-digit band): the base carries it in
        levels 2.1-2.8 times the truth's, 1.02 noise floors on the training
        runs and 10.9 held out; from the levels lowered by a 126- or
        150-digit band, 1.0075 on the training runs and 1.005-1.015 held
        out, the width at 127 (docs/diagnosis.md "Stop 50")."""
        top = ctx.coulomb_digits
        if not np.isfinite(top):
            return []
        return [{"width_digits": float(f * top)} for f in cls.REFINED_SHARES]

    @classmethod
    def drive_taken_digits(cls, params) -> float:
        """Beyond the band the drive loses the width."""
        return float(params["width_digits"])

    @classmethod
    def negligible(cls, params, u_peak: float) -> str:
        """A width below `SMALLEST` of the largest command: what it changes is
        a shift of the friction levels by a fraction of a digit and the
        stick/slip decision at a breakaway on the edge, not a dead band."""
        width = float(params["width_digits"])
        if width < cls.SMALLEST * u_peak:
            return (
                f"a dead zone of {width:.3g} digits is below {cls.SMALLEST:.1%} of the "
                f"largest command ({u_peak:.4g})"
            )
        return ""
