"""The inner rate loop of one inner gimbal, composed of its blocks (paper Fig. 6).

Per sample, with rate reference u_ref = 0 (Sect. 4: keep omega_1 at 0)::

    e      = 0 - gyro reading                      [counts]
    u_pi   = PI(e)                                 [digits]
    u_fb   = notch(u_pi)                           [digits]
    u_nfc  = NFC(omega_2, u_pi, Y)  (if enabled)   [digits]  Eq. 11-14
    u      = bound(u_fb + u_nfc)                   [digits]

The command is held over the next sample (zero-order hold) by the plant.
The loop sees only sensors: the gyro count and the resolver's angle and rate.
"""

from __future__ import annotations

from isp_twin.control.bound import Bound
from isp_twin.control.nfc import FrictionFeedForward
from isp_twin.control.notch import NotchFilter
from isp_twin.control.pi import PIController

__all__ = ["InnerRateLoop"]


class InnerRateLoop:
    """PI + notch + NFC + bound of one inner axis.

    Args:
        pi: the PI block (counts -> digits).
        bound: the command bound.
        notch: the notch block, or None.
        nfc: the friction feed-forward, or None for PI only.
    """

    def __init__(
        self,
        pi: PIController,
        bound: Bound,
        notch: NotchFilter | None = None,
        nfc: FrictionFeedForward | None = None,
    ):
        self.pi = pi
        self.bound = bound
        self.notch = notch
        self.nfc = nfc

    def reset(self) -> None:
        """Reset every block."""
        for block in (self.pi, self.bound, self.notch, self.nfc):
            if block is not None:
                block.reset()

    def step(self, gyro_counts: float, angle: float, omega2: float) -> tuple[float, float, float]:
        """One sample: (command, feedback, nfc) [digits].

        Args:
            gyro_counts: the gyro reading [counts].
            angle: resolver angle [rad].
            omega2: resolver rate [rad/s].
        """
        u_pi = self.pi.step(-gyro_counts)
        u_fb = self.notch.step(u_pi) if self.notch is not None else u_pi
        u_nfc = self.nfc.step(omega2, u_pi, angle) if self.nfc is not None else 0.0
        return self.bound.step(u_fb + u_nfc), u_fb, u_nfc
