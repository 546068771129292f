"""The resolver of a gimbal: quantised relative angle, and its rate.

The NFC (Eq. 11) needs omega_2 and the side Y of the gimbal; the controller
may only use sensors, so both come from the resolver: the angle quantised to
`resolution_deg`, and omega_2 as the angle difference over a window of
`rate_window` samples (a plain difference at 1 kHz would have a rate
resolution of resolution/T, far too coarse near the zero crossings).
"""

from __future__ import annotations

from collections import deque

from isp_twin.units import DEG

__all__ = ["Resolver"]


class Resolver:
    """Quantised angle and windowed-difference rate.

    Args:
        resolution_deg: angle quantum [deg] (e.g. 360/2**20 for a 20-bit RDC).
        rate_window: samples spanned by the rate difference (>= 1).
        dt: sample period [s].
    """

    def __init__(self, resolution_deg: float, rate_window: int, dt: float):
        if not resolution_deg > 0:
            raise ValueError(f"resolver resolution must be > 0, got {resolution_deg}")
        if rate_window < 1:
            raise ValueError(f"resolver rate_window must be >= 1, got {rate_window}")
        self.quantum = resolution_deg * DEG
        self.window = int(rate_window)
        self.dt = dt
        self.reset()

    def reset(self, angle: float = 0.0) -> None:
        """Start at rest at `angle` [rad]."""
        q = round(angle / self.quantum) * self.quantum
        self.past = deque([q] * (self.window + 1), maxlen=self.window + 1)

    def read(self, angle: float) -> tuple[float, float]:
        """One sample: (measured angle [rad], measured rate [rad/s])."""
        q = round(angle / self.quantum) * self.quantum
        self.past.append(q)
        return q, (q - self.past[0]) / (self.window * self.dt)
