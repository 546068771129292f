"""Cogging: a torque ripple periodic in the axis angle (motor slots and magnets)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect


class Cogging(Effect):
    """``accel = amplitude_rad_s2 * sin(2*pi*angle/period_rad + phase_rad)``.

    Parameters: ``amplitude_rad_s2`` [rad/s^2], ``period_rad`` [rad] (2*pi over
    the number of cogging periods per turn), ``phase_rad`` [rad].
    """

    name = "cogging"
    param_names = ("amplitude_rad_s2", "period_rad", "phase_rad")
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {
        "amplitude_rad_s2": 0.0,
        "period_rad": 1.0,
        "phase_rad": 0.0,
    }
    # Periods from 0.5 deg (hundreds of slots) to half a turn (two per turn;
    # one per turn is `unbalance`).
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "amplitude_rad_s2": (0.0, 200.0),
        "period_rad": (0.0087, np.pi + 1e-9),
        "phase_rad": (-2.0 * np.pi, 2.0 * np.pi),
    }

    acceleration_uses_rate = False
    # The periodogram's peaks are separate basins of the period: at a base
    # far from the noise a simulation ranks them by its base error, not by
    # the ripple (stop 45's cogging axis 308: the 115-per-turn peak, the
    # truth, ranked below a 211-per-turn one, whose fit ended 100 times
    # higher in training cost; docs/diagnosis.md "Stop 46").
    every_guess_refined = True

    def acceleration(self, angle, rate):
        p = self.params
        return p["amplitude_rad_s2"] * np.sin(
            2.0 * np.pi * angle / p["period_rad"] + p["phase_rad"]
        )

    @classmethod
    def undetermined(cls, params, travel_rad: float) -> str:
        """A period longer than the travel: the runs see less than one period,
        a smooth torque of the angle that an unbalance or a spring makes as
        well, not a ripple (benchmark unbalance seed 6: a cogging of period
        3.08 rad over a 0.56 rad travel; docs/diagnosis.md "Stop 21")."""
        period = float(params["period_rad"])
        if period > travel_rad:
            return (
                f"a cogging period of {period:.3g} rad is longer than the travel "
                f"({travel_rad:.3g} rad): less than one period, not a ripple"
            )
        return ""

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """The period is searched: the three best peaks of a least-squares
        periodogram of the residual's acceleration against angle."""
        angle, acc = ctx.angle[ctx.moving], ctx.accel[ctx.moving]
        if angle.size < 10:
            return [{"amplitude_rad_s2": 0.0, "period_rad": 0.1, "phase_rad": 0.0}]
        span = float(np.ptp(angle))
        lo, hi = cls.bounds["period_rad"]
        # A ripple the axis crosses in fewer than 4 samples is aliased in
        # 1 kHz data (and in a per-sample model): only resolvable periods.
        step = float(np.quantile(np.abs(ctx.rate[ctx.moving]), 0.9)) * ctx.dt
        lo = max(lo, 4.0 * step)
        # At least two periods inside the travelled range; resolution 1/4 of a
        # period shift across the range.
        hi = min(hi, span / 2.0)
        if hi <= lo:
            return [
                {
                    "amplitude_rad_s2": 0.0,
                    "period_rad": float(min(2 * lo, cls.bounds["period_rad"][1])),
                    "phase_rad": 0.0,
                }
            ]
        freqs = np.arange(1.0 / hi, 1.0 / lo, 0.25 / max(span, 1e-9))[:4000]
        # Cogging is locked to the motor's geometry: whole numbers of periods
        # per turn are always tried (a motor spinning many turns makes the
        # periodogram peaks too narrow for any affordable grid).
        per_turn = np.arange(2, 721) / (2.0 * np.pi)
        freqs = np.union1d(freqs, per_turn[(per_turn >= 1.0 / hi) & (per_turn <= 1.0 / lo)])
        if angle.size > 20000:  # the periodogram costs frequencies x samples
            keep = np.linspace(0, angle.size - 1, 20000).astype(int)
            angle, acc = angle[keep], acc[keep]
        acc = acc - acc.mean()
        a, b, power = (np.empty(freqs.size) for _ in range(3))
        for start in range(0, freqs.size, 256):  # bounded memory
            part = slice(start, start + 256)
            phase = 2.0 * np.pi * np.outer(freqs[part], angle)
            s, c = np.sin(phase), np.cos(phase)
            ss, cc, sc = (s * s).sum(1), (c * c).sum(1), (s * c).sum(1)
            ys, yc = s @ acc, c @ acc
            det = np.maximum(ss * cc - sc * sc, 1e-12)
            a[part] = (cc * ys - sc * yc) / det
            b[part] = (ss * yc - sc * ys) / det
            power[part] = a[part] * ys + b[part] * yc
        out = []
        for i in np.argsort(power)[::-1]:
            if any(abs(freqs[i] - 1.0 / g["period_rad"]) < 1.0 / max(span, 1e-9) for g in out):
                continue
            out.append(
                {
                    "amplitude_rad_s2": float(np.hypot(a[i], b[i])),
                    "period_rad": float(1.0 / freqs[i]),
                    "phase_rad": float(np.arctan2(b[i], a[i])),
                }
            )
            if len(out) == 3:
                break
        return out
