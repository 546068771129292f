"""The names the package shares: gimbal axes, turntable joints, angle sides, friction regimes.

Each is defined here once and imported from here (tests/test_architecture.py
fails on a tuple, list or set literal of two or more of these names anywhere
else in the package).
The independent reference simulator (`isp_twin.reference`) writes the regime
order again on purpose, and a test compares it with `REGIMES`.

Names follow the hardware (STYLE.md): the four gimbals ``outer_az``,
``outer_el``, ``inner_el``, ``inner_az`` on the 3-axis turntable
``table_yaw``, ``table_pitch``, ``table_roll``.

A side of the angle (paper Fig. 3) is an index, `SIDE_R` or `SIDE_L`, in
the code; its letter (`SIDES`) is for output only (report keys, labels).
Which data a fit reads the side from (the measured angle, or a side fixed
for a free-spinning motor) is a different thing: `isp_twin.identification.fit`
calls it the side source.
"""

from __future__ import annotations

from isp_twin.errors import ParameterError

__all__ = [
    "INNER_AXES",
    "OUTER_AXES",
    "GIMBAL_AXES",
    "TABLE_JOINTS",
    "JOINT_CHAIN",
    "SIDES",
    "SIDE_R",
    "SIDE_L",
    "DIRECTIONS",
    "REGIMES",
    "SIDE_SOURCES",
    "check_side",
]

#: The inner gimbals: each carries a gyro and runs a rate loop (the isolated axes).
INNER_AXES: tuple[str, ...] = ("inner_az", "inner_el")
#: The outer gimbals, in the order of the inner gimbal each follows.
OUTER_AXES: tuple[str, ...] = ("outer_az", "outer_el")
#: The four gimbals: the order of parameter files' axes and of every (4,)
#: array of the twin (commands and state).
GIMBAL_AXES: tuple[str, ...] = INNER_AXES + OUTER_AXES
#: The turntable's joints, outermost first (the order of its (3,) arrays).
TABLE_JOINTS: tuple[str, ...] = ("table_yaw", "table_pitch", "table_roll")
#: All seven joints from the ground to the camera, each nested in the one
#: before (the MJCF body tree): the turntable, the outer gimbals, then the
#: inner elevation carrying the inner azimuth.
JOINT_CHAIN: tuple[str, ...] = TABLE_JOINTS + OUTER_AXES + INNER_AXES[::-1]

#: Sides of the angle by index (Fig. 3): R for angle > 0, L for angle <= 0.
SIDES: tuple[str, ...] = ("R", "L")
SIDE_R, SIDE_L = 0, 1
#: Directions of motion by index: + and - (the rate's sign while moving, the
#: drive's at rest; zero counts as +).
DIRECTIONS: tuple[str, ...] = ("+", "-")
#: The friction regimes in the order of the paper's parameter vector X
#: (Eq. 8): index = 2 * side + direction (`isp_twin.model.friction.regime_of`).
REGIMES: tuple[str, ...] = tuple(s + d for s in SIDES for d in DIRECTIONS)
#: Side sources: where each step's side (R/L half-plane) is read from (the
#: fused or raw measured angle, the wrapped angle, or a fixed side); a fit's
#: option (`isp_twin.identification.side_angle`) and a parameter file's record
#: of it (``fitted_with.side_source``).
SIDE_SOURCES: tuple[str, ...] = ("measured", "raw", "wrap", "right", "left")


def check_side(side: int | None) -> int | None:
    """A fixed side as given (`SIDE_R`, `SIDE_L`, or None for "read it from the angle").

    Raises:
        ParameterError: anything else (a float such as 1.0 is refused: it
            would read as `SIDE_L`).
    """
    if side is None or (type(side) is int and side in (SIDE_R, SIDE_L)):
        return side
    raise ParameterError(
        f"side {side!r}: expected SIDE_R ({SIDE_R}), SIDE_L ({SIDE_L}) or None "
        "(from isp_twin.vocabulary)"
    )
