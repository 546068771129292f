"""Dynamic friction with pre-sliding: the bristle state of the LuGre model.

The steady part of friction is already the Stribeck law of Eq. 5; this adds
the LuGre bristle force ``sigma0*z`` with ``dz/dt = v - |v|*z/z_max`` (LuGre
with a constant g = sigma0*z_max, sigma1 = sigma2 = 0). In steady sliding it
is a Coulomb-like term; after a reversal it takes a displacement of about
``z_max`` (the pre-sliding distance) to turn round, which the static map
cannot produce.

The force over a sample is the mean of ``sigma0*z`` over it for the rate held
(not its value at the sample's start): where the axis travels more than
``z_max`` in one sample (a small pre-sliding distance, a fast axis) the
bristles turn round within the sample, and the value at its start would
hold the old direction's force for all of it. Measured on reference axes
(dev seeds 1000-1005 of issue 8, true rate form and true LuGre): held-out RMS
error 1.01-3.56 noise floors with the mean, 1.02-7.55 with the start value
(docs/diagnosis.md, "Resonance and LuGre on reference axes").

That per-sample form serves Eq. 6 and the twin. The sub-stepped model
(m > 1) integrates z inside its sub-steps with the friction and the stick
test instead (`in_substeps`, `substep_columns`): on the same axes 0.98-1.03
noise floors (docs/diagnosis.md, "Stop 17 B").
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect


class LuGre(Effect):
    """``accel = -accel_rad_s2 * mean(z) / presliding_rad`` while moving.

    The bristle deflection z [rad] follows the exact solution of the LuGre
    state equation for a rate held over one sample, and the acceleration is
    its mean over the sample (the exact zero-order hold of the bristle force
    for that rate). At rest the bristles hold
    their deflection and their force is part of the static friction (Eq. 5),
    so the term is zero there.

    Parameters: ``accel_rad_s2`` [rad/s^2] (sigma0*z_max / J),
    ``presliding_rad`` [rad] (z_max).
    """

    name = "lugre"
    param_names = ("accel_rad_s2", "presliding_rad")
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"accel_rad_s2": 0.0, "presliding_rad": 1.0}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "accel_rad_s2": (0.0, 500.0),
        "presliding_rad": (1e-5, 0.05),
    }

    #: The sub-stepped model integrates z with the friction, sub-step by
    #: sub-step (`isp_twin.model.substep_model`); `acceleration` serves Eq. 6
    #: and the twin.
    in_substeps = True
    #: The read-out refit of reference LuGre 337 needs the model's own slopes
    #: (`Effect.fine_slopes`).
    fine_slopes = True

    def substep_columns(self, dt: float, m: int) -> dict[str, object]:
        """The bristle drive at full deflection ``accel_rad_s2 * dt`` [rad/s per
        sample] and the pre-sliding distance [rad]."""
        return {
            "bristle_drive": np.asarray(self.params["accel_rad_s2"]) * dt,
            "presliding_rad": self.params["presliding_rad"],
        }

    def reset(self) -> None:
        self._z = np.zeros(np.shape(self.params["presliding_rad"]))

    def acceleration(self, angle, rate):
        zmax = self.params["presliding_rad"]
        rate = np.asarray(rate, dtype=float)
        z_ss = zmax * np.sign(rate)
        # z(t) = z_ss + (z0 - z_ss) exp(-s t / dt), s = |rate| dt / zmax; its
        # mean over the sample is z_ss + (z0 - z_ss) (1 - exp(-s)) / s.
        s = np.abs(rate) * self.dt / zmax
        decay = np.exp(-s)
        small = s < 1e-9
        mean_factor = np.where(small, 1.0, (1.0 - decay) / np.where(small, 1.0, s))
        z_mean = z_ss + (self._z - z_ss) * mean_factor
        acc = np.where(rate != 0.0, -self.params["accel_rad_s2"] * z_mean / zmax, 0.0)
        self._z = z_ss + (self._z - z_ss) * decay
        return acc

    @classmethod
    def sliding_friction_rad_s2(cls, params) -> float:
        """In steady sliding the bristles sit at ``z_max``: the force ``accel_rad_s2``."""
        return float(params["accel_rad_s2"])

    @classmethod
    def _sliding(cls, ctx) -> float:
        """The sliding friction the data show [rad/s^2]: the model's Coulomb
        level plus what its residual shows it lacks (`ResidualContext`);
        NaN where neither is known."""
        sliding = ctx.coulomb_rad_s2 + max(ctx.friction_deficit_rad_s2, 0.0)
        return sliding if np.isfinite(sliding) and sliding > 0.0 else float("nan")

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """A grid: bristle force 5 % to 100 % of the sliding friction
        (`_sliding`; 4 to 40 rad/s^2 where it is not known), pre-sliding
        0.3 to 20 mrad (geometric): ranked at the current rate parameters,
        right where those lack the bristle force (a parameter file made
        without it)."""
        sliding = cls._sliding(ctx)
        forces = (
            np.geomspace(4.0, 40.0, 10)
            if np.isnan(sliding)
            else sliding * np.geomspace(0.05, 1.0, 10)
        )
        return [
            {"accel_rad_s2": float(a), "presliding_rad": float(z)}
            for a in forces
            for z in np.geomspace(3e-4, 2e-2, 14)
        ]

    @classmethod
    def refined_starts(cls, ctx) -> list[dict[str, float]]:
        """Six starts refined beside the best guess: bristle force 20 % and
        50 % of the sliding friction (`_sliding`; 4 and 10 rad/s^2 where it
        is not known), pre-sliding 0.2, 0.6 and 2 mrad.

        In steady sliding the bristle force is a Coulomb term, so a model
        fitted without it carries it in its Coulomb level, which bounds it;
        each start has that level lowered by it (`sliding_friction_rad_s2`,
        `isp_twin.diagnosis.candidates`). Simulated at the base's rate
        parameters the larger forces all look worse than the smallest, yet
        refined they fit best (benchmark LuGre seeds 1 and 2,
        docs/diagnosis.md "Stop 23")."""
        sliding = cls._sliding(ctx)
        forces = (4.0, 10.0) if np.isnan(sliding) else (0.2 * sliding, 0.5 * sliding)
        return [
            {"accel_rad_s2": float(a), "presliding_rad": z}
            for a in forces
            for z in (2e-4, 6e-4, 2e-3)
        ]
