"""The reference simulator's own physics of each effect of the project's library.

Each effect is a frozen dataclass in physical units (N·m, rad, digits) with
``name``, the name of the matching effect of the project (`isp_twin.model.effects`),
and ``truth(axis)``: its parameters written in that effect's names and units,
so a fit can be judged against the truth (torques become accelerations
torque / J with J the total inertia of the axis). Nothing here is imported from
the project's effect code: the equations are written again from the physics.

Kinds, as `isp_twin.reference.axis.simulate` applies them:

* angle torques (`Cogging`, `CableSpring`, `Unbalance`, `TorqueOffset`):
  ``torque_nm(theta)`` [N·m], evaluated at every integration step. The
  compiled integrator takes their parameters from a table and evaluates the
  same expressions (`axis._angle_torque`);
  `tests/test_reference_physics.py` checks that the two agree bit for bit;
* command path (`InputDelay`, then `Deadzone`, `Saturation`): the amplifier's
  input on the integration grid (a delay is continuous time, rounded to the
  integration step, so it can be a fraction of a sample);
* states (`PayloadMode`, a second inertia on a spring-damper; `Bristles`,
  the LuGre bristle deflection): integrated with the axis;
* gyro (`GyroError`): bias and scale factor of the reading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from isp_twin.errors import ParameterError

__all__ = [
    "Cogging",
    "CableSpring",
    "Unbalance",
    "TorqueOffset",
    "InputDelay",
    "Deadzone",
    "Saturation",
    "GyroError",
    "PayloadMode",
    "Bristles",
    "EFFECT_TYPES",
]


@dataclass(frozen=True)
class Cogging:
    """Torque ripple of the motor's slots: ``A sin(2 pi theta / period + phase)``.

    Attributes:
        amplitude_nm: A [N·m].
        period_rad: angular period [rad] (2 pi / periods per turn).
        phase_rad: phase at theta = 0 [rad].
    """

    name: ClassVar[str] = "cogging"
    amplitude_nm: float
    period_rad: float
    phase_rad: float

    def torque_nm(self, theta: float) -> float:
        return self.amplitude_nm * math.sin(
            2.0 * math.pi * theta / self.period_rad + self.phase_rad
        )

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {
            "amplitude_rad_s2": self.amplitude_nm / inertia_kg_m2,
            "period_rad": self.period_rad,
            "phase_rad": self.phase_rad,
        }


@dataclass(frozen=True)
class CableSpring:
    """A cable bundle: a spring about its neutral angle, ``-k (theta - centre)``.

    Attributes:
        stiffness_nm_rad: k [N·m/rad] (> 0 pulls back to the centre).
        centre_rad: the angle where the cable exerts no torque [rad].
    """

    name: ClassVar[str] = "cable_spring"
    stiffness_nm_rad: float
    centre_rad: float

    def torque_nm(self, theta: float) -> float:
        return -self.stiffness_nm_rad * (theta - self.centre_rad)

    def energy_j(self, theta: float) -> float:
        """Potential energy stored in the spring [J]."""
        return 0.5 * self.stiffness_nm_rad * (theta - self.centre_rad) ** 2

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {
            "stiffness_1_s2": self.stiffness_nm_rad / inertia_kg_m2,
            "offset_rad_s2": self.stiffness_nm_rad * self.centre_rad / inertia_kg_m2,
        }


@dataclass(frozen=True)
class Unbalance:
    """Gravity on an off-axis centre of mass: ``m g r sin(theta + phase)``.

    Attributes:
        amplitude_nm: m g r [N·m].
        phase_rad: direction of the centre of mass at theta = 0, gravity included [rad].
    """

    name: ClassVar[str] = "unbalance"
    amplitude_nm: float
    phase_rad: float

    def torque_nm(self, theta: float) -> float:
        return self.amplitude_nm * math.sin(theta + self.phase_rad)

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {
            "amplitude_rad_s2": self.amplitude_nm / inertia_kg_m2,
            "phase_rad": self.phase_rad,
        }


@dataclass(frozen=True)
class TorqueOffset:
    """A constant torque (amplifier offset, a steady wind-up) [N·m]."""

    name: ClassVar[str] = "torque_offset"
    torque_offset_nm: float

    def torque_nm(self, theta: float) -> float:
        return self.torque_offset_nm

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {"accel_rad_s2": self.torque_offset_nm / inertia_kg_m2}


@dataclass(frozen=True)
class InputDelay:
    """Transport delay of the command (bus, digital amplifier) [s].

    The simulator shifts the held command by whole integration steps, so the
    delay in effect is `steps(h) * h`; a delay that is not a multiple of the
    step is refused rather than silently rounded.
    """

    name: ClassVar[str] = "input_delay"
    delay_s: float

    def steps(self, step_s: float) -> int:
        """The delay in integration steps of ``step_s`` [s].

        Raises:
            ParameterError: negative, or not a whole number of steps.
        """
        steps = self.delay_s / step_s
        whole = round(steps)
        if self.delay_s < 0.0 or abs(steps - whole) > 1e-6:
            raise ParameterError(
                f"input delay {self.delay_s:g} s: must be >= 0 and a whole number of "
                f"integration steps of {step_s:g} s"
            )
        return int(whole)

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {"delay_s": self.delay_s}


@dataclass(frozen=True)
class Deadzone:
    """Amplifier dead band: ``sign(u) max(|u| - width, 0)`` [digits]."""

    name: ClassVar[str] = "deadzone"
    width_digits: float

    def amplify(self, u: np.ndarray) -> np.ndarray:
        return np.sign(u) * np.maximum(np.abs(u) - self.width_digits, 0.0)

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {"width_digits": self.width_digits}


@dataclass(frozen=True)
class Saturation:
    """Amplifier limit: ``clip(u, -limit, limit)`` [digits]."""

    name: ClassVar[str] = "saturation"
    limit_digits: float

    def amplify(self, u: np.ndarray) -> np.ndarray:
        return np.clip(u, -self.limit_digits, self.limit_digits)

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {"limit_digits": self.limit_digits}


@dataclass(frozen=True)
class GyroError:
    """Gyro bias and scale-factor error: ``reading = bias + (1 + scale) rate``.

    Attributes:
        bias_rad_s: bias [rad/s].
        scale: scale-factor error [1].
    """

    name: ClassVar[str] = "sensor_bias"
    bias_rad_s: float
    scale: float

    def read(self, rate: np.ndarray) -> np.ndarray:
        return self.bias_rad_s + (1.0 + self.scale) * np.asarray(rate)

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {"bias_rad_s": self.bias_rad_s, "scale": self.scale}


@dataclass(frozen=True)
class PayloadMode:
    """A flexible payload: a second inertia J2 on a spring-damper (two-mass model).

    The motor side (inertia J1 = J - J2, with friction) drives the payload
    through the spring k and damper c; the gyro sits on the payload, the
    resolver on the motor side. In the centre-of-mass rate
    ``w = (J1 w1 + J2 w2) / J`` (``J w' =`` the external torques: the spring is
    internal) and ``y = (J1 / J) x`` with ``x`` the payload's deflection from
    the motor side, the two-mass equations are exactly
    ``y'' + (c/mu) y' + (k/mu) y = -w'`` with ``mu = J1 J2 / J``, and the gyro
    reads ``w2 = w + y'``: the project's `resonance` effect on a rigid axis of
    inertia J, with ``freq_hz = sqrt(k/mu) / 2 pi`` (the free two-mass mode),
    ``damping_ratio = c / (2 sqrt(k mu))``, ``coupling = 1`` and
    ``payload_fraction = J2/J`` (`truth`). Friction and stick act on the
    motor side's rate ``w1 = w - (J2/J1) y'``, not on w (a motor side held by
    stiction lets the payload ring at the clamped frequency sqrt(k/J2)), and
    the resolver reads ``theta1 = theta - (J2/J1) y``: the project's
    `resonance` holds that only in its sub-stepped model (m > 1) and with
    ``payload_fraction`` > 0 (docs/diagnosis.md, "Stop 18 R").

    Before issue 8's resonance work `truth` gave the clamped frequency
    sqrt(k/J2) and c / (2 sqrt(k J2)) (the payload equation in the motor
    side's acceleration, the reaction on the motor left out): on reference
    dev seeds 1000-1003 the library with the true rate form and those values
    was further from the data than with no resonance at all
    (docs/diagnosis.md, "Resonance and LuGre on reference axes").

    Attributes:
        payload_fraction: J2 / J [1], 0 < f < 1.
        stiffness_nm_rad: k [N·m/rad].
        damping_nm_s_rad: c [N·m·s/rad].
    """

    name: ClassVar[str] = "resonance"
    payload_fraction: float
    stiffness_nm_rad: float
    damping_nm_s_rad: float

    def __post_init__(self) -> None:
        if not 0.0 < self.payload_fraction < 1.0 or self.stiffness_nm_rad <= 0.0:
            raise ParameterError(
                "payload mode: needs 0 < payload_fraction < 1 and stiffness > 0, got "
                f"{self.payload_fraction}, {self.stiffness_nm_rad}"
            )

    def clamped_freq_hz(self, inertia_kg_m2: float) -> float:
        """Natural frequency of the payload with the motor side held [Hz]."""
        j2 = self.payload_fraction * inertia_kg_m2
        return math.sqrt(self.stiffness_nm_rad / j2) / (2.0 * math.pi)

    def free_freq_hz(self, inertia_kg_m2: float) -> float:
        """Undamped frequency of the free two-mass mode [Hz]."""
        j2 = self.payload_fraction * inertia_kg_m2
        j1 = inertia_kg_m2 - j2
        return math.sqrt(self.stiffness_nm_rad * (1.0 / j1 + 1.0 / j2)) / (2.0 * math.pi)

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        """The free mode in the project's `resonance` parameters (class doc)."""
        j2 = self.payload_fraction * inertia_kg_m2
        mu = (inertia_kg_m2 - j2) * j2 / inertia_kg_m2
        return {
            "freq_hz": self.free_freq_hz(inertia_kg_m2),
            "damping_ratio": self.damping_nm_s_rad / (2.0 * math.sqrt(self.stiffness_nm_rad * mu)),
            "coupling": 1.0,
            "payload_fraction": self.payload_fraction,
        }


@dataclass(frozen=True)
class Bristles:
    """LuGre bristles on top of the Stribeck law: torque ``sigma0 z`` while moving,
    ``dz/dt = w - |w| z / z_max`` (LuGre with g = sigma0 z_max constant,
    sigma1 = sigma2 = 0); at rest the bristles hold their deflection.

    Attributes:
        stiffness_nm_rad: sigma0 [N·m/rad].
        presliding_rad: z_max, the pre-sliding displacement [rad].
    """

    name: ClassVar[str] = "lugre"
    stiffness_nm_rad: float
    presliding_rad: float

    def truth(self, inertia_kg_m2: float) -> dict[str, float]:
        return {
            "accel_rad_s2": self.stiffness_nm_rad * self.presliding_rad / inertia_kg_m2,
            "presliding_rad": self.presliding_rad,
        }


#: Effect name (the project's) -> the reference's class.
EFFECT_TYPES: dict[str, type] = {
    cls.name: cls
    for cls in (
        Cogging,
        CableSpring,
        Unbalance,
        TorqueOffset,
        InputDelay,
        Deadzone,
        Saturation,
        GyroError,
        PayloadMode,
        Bristles,
    )
}
