"""A flexible payload as a two-mass system, integrated in the sub-stepped model's sub-steps.

Not (yet) in the effect library `isp_twin.model.effects.EFFECTS`: `diagnose`
does not try it, and a parameter file cannot name it; `register` it to use
it by name (`benchmarks/truth_held.py` does). Its kernel physics is in
`isp_twin.model.substep_model`; why it exists: docs/diagnosis.md, "Stop 17 B".
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.resonance import Resonance, _discretize

__all__ = ["TwoMassResonance"]


class TwoMassResonance(Resonance):
    """A flexible payload as a second inertia on a spring-damper (two-mass).

    In the centre-of-mass rate w the payload coordinate y obeys
    ``y'' + 2*zeta*wn*y' + wn^2*y = -w'`` (`Resonance` with coupling 1, wn the
    free two-mass mode) and the gyro on the payload reads ``w + y'``; what
    `Resonance` cannot hold: friction, the stick test and the viscous torque
    act on the motor side's rate ``w - r*y'``, ``r = J2/J1``, and a motor
    side held by stiction lets the payload ring at the clamped frequency
    ``wn/sqrt(1 + r)`` (docs/reference_simulator.md). The sub-stepped model
    (m > 1) integrates it in its sub-steps (`in_substeps`); Eq. 6 and the twin
    use `Resonance`'s gyro-only form with coupling 1. Not in `EFFECTS`
    (diagnose does not try it yet: docs/diagnosis.md, "Stop 17 B").

    Parameters: ``freq_hz`` [Hz] (free mode), ``damping_ratio`` [1],
    ``payload_fraction`` [1] (J2/J, 0 < f < 1).
    """

    name = "two_mass_resonance"
    param_names = ("freq_hz", "damping_ratio", "payload_fraction")
    null: ClassVar[dict[str, float]] = {
        "freq_hz": 100.0,
        "damping_ratio": 0.1,
        "payload_fraction": 1e-6,
    }
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "freq_hz": (1.0, 400.0),
        "damping_ratio": (0.002, 0.5),
        "payload_fraction": (1e-6, 0.9),
    }
    in_substeps = True

    def reset(self) -> None:
        self._phi, self._gamma = _discretize(
            self.params["freq_hz"], self.params["damping_ratio"], 1.0, self.dt
        )
        self._state = np.zeros(self._gamma.shape)
        self._last = None

    def substep_columns(self, dt: float, m: int) -> dict[str, object]:
        """J2/J1, the spring's pull on the motor side and the mode's sub-step
        transitions, free and clamped (`isp_twin.model.substep_model.STATE_COLUMNS`)."""
        f = np.asarray(self.params["payload_fraction"], dtype=float)
        r = f / (1.0 - f)
        zeta = np.asarray(self.params["damping_ratio"], dtype=float)
        wn = 2.0 * np.pi * np.asarray(self.params["freq_hz"], dtype=float)
        phi, gamma = _discretize(self.params["freq_hz"], zeta, 1.0, dt / m)
        # Motor side clamped: (1 + r) y'' + 2 zeta wn y' + wn^2 y = 0.
        stretch = np.sqrt(1.0 + r)
        clamped, _ = _discretize(self.params["freq_hz"] / stretch, zeta / stretch, 0.0, dt / m)
        cols = {
            "payload_ratio": r,
            # Spring and damper torque on the motor side / J, per y and per y'.
            "spring_y": r / (1.0 + r) * wn * wn,
            "spring_yd": r / (1.0 + r) * 2.0 * zeta * wn,
            "free_g0": gamma[..., 0],
            "free_g1": gamma[..., 1],
        }
        for a, b in ((0, 0), (0, 1), (1, 0), (1, 1)):
            cols[f"free_{a}{b}"] = phi[..., a, b]
            cols[f"clamped_{a}{b}"] = clamped[..., a, b]
        return cols
