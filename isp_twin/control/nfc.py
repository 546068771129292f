"""Nonlinear friction feed-forward compensation NFC (paper Eq. 11-14).

Per sample k, from the identified friction model (Eq. 5, parameters of Table 2):

* Eq. 11: ``u_c1(k) = T_f(omega_2, T_m, Y, k) / K_e`` [digits]. In the rate form
  of `RateParams` the unidentifiable b cancels: ``T_f/K_e = (b*T_f)/(b*K_e)``,
  i.e. friction / gain of the regime in force;
* Eq. 12: ``u_c2(k) = mean(u_c1(k), u_c1(k-1), u_c1(k-2), u_c1(k-3))``;
* Eq. 13: ``u_c3(k) = gamma * u_c2(k)``, gamma <= 1 (slight under-compensation).

What Eq. 11 leaves open, decided here:

* omega_2 is what the controller can know: the rate of the resolver angle
  (relative to the parent gimbal), not the true state. At or below
  `rest_rate` the axis counts as at rest (default 0: the resolver did not
  move over its rate window).
* At rest Eq. 5 says T_f = T_m up to the breakaway T_s. T_m is taken as the
  feedback (PI) command's torque, not the total, so the compensation does not
  feed on itself: at rest ``u_c1 = clip(u_pi, -T_s/K_e, T_s/K_e)``; its sign
  picks the direction of the regime.
"""

from __future__ import annotations

import numpy as np

from isp_twin.model.friction import regime_of, side_of, sliding, stiction
from isp_twin.model.parameters import RateParams

__all__ = ["FrictionFeedForward"]


class FrictionFeedForward:
    """NFC of one inner axis.

    Args:
        params: the identified rate-form parameters of the axis (arrays (4,)).
        gamma: attenuation factor of Eq. 13, in (0, 1] (paper: 0.95, range 0.90-0.98).
        taps: length of the moving average of Eq. 12 (paper: 4).
        rest_rate: |omega_2| below which the axis counts as at rest [rad/s].
    """

    def __init__(
        self, params: RateParams, gamma: float = 0.95, taps: int = 4, rest_rate: float = 0.0
    ):
        if not 0.0 < gamma <= 1.0:
            raise ValueError(f"NFC gamma must lie in (0, 1], got {gamma}")
        if taps < 1:
            raise ValueError(f"NFC taps must be >= 1, got {taps}")
        if rest_rate < 0:
            raise ValueError(f"NFC rest_rate must be >= 0, got {rest_rate}")
        gain = np.asarray(params.gain, dtype=float)
        if gain.shape != (4,) or np.any(gain <= 0):
            raise ValueError("NFC needs one axis' parameters with positive gains, shape (4,)")
        # Per regime, in digits: T_s/K_e, T_c/K_e; alpha [s/rad].
        self.static_digits = tuple(float(x) for x in np.asarray(params.static) / gain)
        self.coulomb_digits = tuple(float(x) for x in np.asarray(params.coulomb) / gain)
        self.alpha = tuple(float(x) for x in np.asarray(params.alpha))
        self.gamma = float(gamma)
        self.taps = int(taps)
        self.rest_rate = float(rest_rate)
        self.reset()

    def reset(self) -> None:
        """Clear the smoothing history."""
        self.history = [0.0] * self.taps
        self.pos = 0

    def friction_digits(self, omega2: float, u_pi: float, angle: float) -> float:
        """Eq. 11: the model friction as an amplifier command u_c1 [digits]."""
        if abs(omega2) > self.rest_rate:
            r = regime_of(side_of(angle, omega2), omega2)
            return sliding(omega2, self.static_digits[r], self.coulomb_digits[r], self.alpha[r])
        return stiction(u_pi, self.static_digits[regime_of(side_of(angle, u_pi), u_pi)])

    def step(self, omega2: float, u_pi: float, angle: float) -> float:
        """One sample of Eq. 14: the compensation u_c3 [digits].

        Args:
            omega2: relative rate estimate [rad/s].
            u_pi: the feedback command this sample [digits].
            angle: relative angle estimate [rad] (its sign picks the half-plane).
        """
        u1 = self.friction_digits(omega2, u_pi, angle)
        self.history[self.pos] = u1
        self.pos = (self.pos + 1) % self.taps
        return self.gamma * sum(self.history) / self.taps
