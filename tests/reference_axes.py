"""Reference-simulator axes shared by tests (`isp_twin.reference`, which shares
no code with the model)."""

from __future__ import annotations

from isp_twin.reference import Axis, RegimeFriction

#: A fast axis (J 0.007 kg m^2, 1.35 N m s/rad: a 5.2 ms time constant),
#: breakaway 0.36-0.50 N m, Coulomb 0.14-0.20 N m, reached by about 500
#: digits of its 9.5e-4 N m/digit drive.
FAST_AXIS = Axis(
    0.007,
    1.35,
    9.5e-4,
    (
        RegimeFriction(0.48, 0.19, 70.0),
        RegimeFriction(0.42, 0.17, 73.0),
        RegimeFriction(0.36, 0.14, 72.0),
        RegimeFriction(0.50, 0.20, 80.0),
    ),
)
