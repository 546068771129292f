"""Unit conversions at the edges.

Inside the code everything is SI (rad, rad/s, s, N·m). The paper's units
(deg, deg/s, amplifier digits) appear only in files and printed output and are
converted once, here.
"""

from __future__ import annotations

import math

__all__ = ["DEG", "deg_to_rad", "rad_to_deg"]

#: One degree in radians.
DEG = math.pi / 180.0


def deg_to_rad(x):
    """Degrees (or deg/s) to radians (or rad/s); works on arrays."""
    return x * DEG


def rad_to_deg(x):
    """Radians (or rad/s) to degrees (or deg/s); works on arrays."""
    return x / DEG
