"""The bound on the control quantity (paper Sect. 4.1): a symmetric saturation."""

from __future__ import annotations

import math

__all__ = ["Bound"]


class Bound:
    """Clamp the command to ``[-limit, limit]`` [amplifier digits].

    The paper's amplifier input is a signed digital word; its open-loop test
    drives 950 digits (Eq. 4), so the bound is at least that.
    """

    def __init__(self, limit: float):
        if not (limit > 0 and not math.isnan(limit)):
            raise ValueError(f"bound limit must be > 0, got {limit}")
        self.limit = float(limit)

    def step(self, u: float) -> float:
        """The bounded command."""
        lim = self.limit
        return lim if u > lim else (-lim if u < -lim else u)

    def reset(self) -> None:
        """Stateless; present for symmetry with the other blocks."""
