"""A constant torque on the axis (amplifier offset, unbalance at a fixed attitude)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect
from isp_twin.model.parameters import sample_hold_factor


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


@dataclass(frozen=True)
class ImpliedOffset:
    """The constant torque the fitted per-direction Coulomb levels imply.

    A constant torque T0 is, for Eq. 5 with levels per direction, exactly
    ``Tc+ -> Tc+ - T0``, ``Tc- -> Tc- + T0`` (and the same for Ts), on both
    angle sides (docs/diagnosis.md, "Sensor bias and torque offset"). So the levels imply
    ``(Tc- - Tc+) / 2`` on each side: the offset plus half the bearings' own
    asymmetry, which the data cannot separate from it. Values as torque / J.

    Attributes:
        right_rad_s2, left_rad_s2: ``(Tc- - Tc+) / (2 J)`` on each side [rad/s^2].
        right_ci95, left_ci95: their 95 % half-widths [rad/s^2].
        value_rad_s2: the two sides' inverse-variance mean [rad/s^2].
        ci95: its half-width [rad/s^2].
        consistent: the two sides agree within their combined 95 % interval
            (a real constant torque is the same on both sides).
    """

    right_rad_s2: float
    left_rad_s2: float
    right_ci95: float
    left_ci95: float
    value_rad_s2: float
    ci95: float
    consistent: bool


def implied_offset(
    pole: np.ndarray,
    coulomb: np.ndarray,
    coulomb_ci95: np.ndarray,
    dt: float,
    exact_hold: bool = True,
) -> ImpliedOffset:
    """`ImpliedOffset` of rate-form parameters (regimes R+, R-, L+, L-).

    Args:
        pole: per-regime pole a, (4,).
        coulomb: per-regime b·Tc [rad/s per sample], (4,).
        coulomb_ci95: their 95 % half-widths, (4,) (NaN: unknown).
        dt: sample period [s].
        exact_hold: a torque held over the sample moves the rate by
            ``accel*T*(1 - a)/(-ln a)`` (`Integration.exact_effect_hold`),
            else by ``accel*T`` (Eq. 6): the same factor converts b·Tc to Tc/J.
    """
    hold = sample_hold_factor(pole) if exact_hold else np.ones(4)
    per_accel = 1.0 / (hold * dt)
    acc = np.asarray(coulomb, float) * per_accel
    ci = np.asarray(coulomb_ci95, float) * per_accel
    sides = []
    for plus in (0, 2):
        value = 0.5 * (acc[plus + 1] - acc[plus])
        half = 0.5 * float(np.hypot(ci[plus], ci[plus + 1]))
        sides.append((float(value), half))
    (vr, cr), (vl, cl) = sides
    if np.isfinite(cr) and np.isfinite(cl) and cr > 0.0 and cl > 0.0:
        wr, wl = 1.0 / cr**2, 1.0 / cl**2
        value = (wr * vr + wl * vl) / (wr + wl)
        ci95 = float(1.0 / np.sqrt(wr + wl))
        consistent = bool(abs(vr - vl) <= np.hypot(cr, cl))
    else:
        value, ci95, consistent = 0.5 * (vr + vl), float("nan"), False
    return ImpliedOffset(vr, vl, cr, cl, float(value), ci95, consistent)
