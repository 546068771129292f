"""Random reference axes over a wide, physically plausible range.

The ranges (all drawn independently; "log" = log-uniform):

==========================  =====================================  ==========================
quantity                    range                                  why
==========================  =====================================  ==========================
inertia J                   log 0.002-0.05 kg·m^2                  a small gimbal (scale only)
time constant J/eta         log 5 ms-1 s                           issue 8; direct drive to
                                                                   heavily geared
no-friction top rate        log 30-300 deg/s at 1000 digits        gimbal slew rates
 Km*1000/eta
Tc / peak drive             log 0.05 to 0.6/(Ts/Tc), per regime    issue 8: 5-60 % of the
                            x 0.8-1.25 (same bearings: the four    peak drive Km*1000
                            regimes differ, not wildly)
Ts / Tc                     1-2.5, per regime x 0.9-1.1, clipped   issue 8
Stribeck speed 1/alpha      log 0.005-0.5 x top rate (alpha over   two decades (issue 8)
                            two decades), per regime x 0.8-1.25
viscous, motor gain         x 0.8-1.25 per regime                  Table 2 differs per regime
gyro noise                  log 0.01-0.1 deg/s                     MEMS to tactical FOG
resolver                    14-19 bits per turn                    common resolvers/encoders
==========================  =====================================  ==========================

Effects, at a random realistic strength (P = the peak drive torque Km*1000,
sigma = the gyro noise). Each is large enough to show in the response (the
experiment design checks that it moves the noise-free gyro reading by at least
`MIN_FOOTPRINT_SIGMA` noise sigmas RMS, see `isp_twin.reference.experiment`)
and within what a small gimbal shows:

==============  ===========================================================================
cogging         amplitude 0.03-0.15 P; 24-180 periods per turn (2-15 deg); phase uniform
cable_spring    torque 0.05-0.3 P at 20 deg from the centre; centre +-10 deg
unbalance       m g r = 0.05-0.3 P; phase uniform
torque_offset   0.05-0.2 P, either sign
input_delay     1-10 ms in 0.1 ms steps (whole and fractional samples)
deadzone        5-20 % of 1000 digits
saturation      55-85 % of 1000 digits (the excitations reach 80-100 %)
sensor_bias     bias 5-20 sigma, either sign; scale error 0.5-3 %, either sign
resonance       payload J2 = 5-30 % of J; clamped frequency log 15-80 Hz; damping 0.01-0.08
lugre           z_max log 0.2-5 mrad; sigma0 z_max = 0.05-0.2 P
==============  ===========================================================================

`draw_axis(seed, effect)` is reproducible, and the base axis of a seed is the
same for every effect (the effect is drawn from its own stream), so cases can
be compared axis by axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from isp_twin.errors import ParameterError
from isp_twin.reference import effects as fx
from isp_twin.reference.axis import Axis, RegimeFriction, Sensors

__all__ = ["COMMAND_SCALE_DIGITS", "EFFECT_NAMES", "DrawnAxis", "draw_axis"]

#: The command range the draws refer to [digits] (the paper's Eq. 7 uses 950).
COMMAND_SCALE_DIGITS = 1000.0
#: Effects the generator draws, in the project's names.
EFFECT_NAMES: tuple[str, ...] = tuple(fx.EFFECT_TYPES)
#: The integration step the delays are rounded to [s] (10 kHz).
_STEP_S = 1e-4
_DEG = math.pi / 180.0


@dataclass(frozen=True)
class DrawnAxis:
    """One random axis.

    Attributes:
        seed: the seed it was drawn from.
        effect: the effect's project name, or "none".
        attempt: redraw index (the experiment design redraws an axis it cannot excite).
        axis: the rigid axis and friction.
        effects: zero or one reference effect object.
        sensors: gyro and resolver.
        peak_drive_nm: Km * `COMMAND_SCALE_DIGITS` [N·m].
    """

    seed: int
    effect: str
    attempt: int
    axis: Axis
    effects: tuple[object, ...]
    sensors: Sensors
    peak_drive_nm: float


def _log(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_axis(seed: int, effect: str | None = None, attempt: int = 0) -> DrawnAxis:
    """A random axis, with one effect of the library or none.

    Args:
        seed: any non-negative integer.
        effect: a name of `EFFECT_NAMES`, or None / "none".
        attempt: redraw index (0 first).

    Raises:
        ParameterError: unknown effect name or negative seed.
    """
    name = "none" if effect in (None, "none") else str(effect)
    if name != "none" and name not in fx.EFFECT_TYPES:
        raise ParameterError(
            f"unknown reference effect '{name}'; known: none, {', '.join(EFFECT_NAMES)}"
        )
    if seed < 0 or attempt < 0:
        raise ParameterError(
            f"reference draw: seed and attempt must be >= 0, got {seed}, {attempt}"
        )
    rng = np.random.default_rng([seed, attempt, 0])
    inertia = _log(rng, 0.002, 0.05)
    tau = _log(rng, 0.005, 1.0)
    eta = inertia / tau
    top_rate = _log(rng, 30.0, 300.0) * _DEG
    km = top_rate * eta / COMMAND_SCALE_DIGITS
    peak = km * COMMAND_SCALE_DIGITS
    ratio = rng.uniform(1.0, 2.5)
    tc_frac = _log(rng, 0.05, 0.6 / ratio)
    stribeck_speed = _log(rng, 0.005, 0.5) * top_rate
    regimes = []
    for _ in range(4):
        r = float(np.clip(ratio * rng.uniform(0.9, 1.1), 1.0, 2.5))
        tc = float(np.clip(tc_frac * _log(rng, 0.8, 1.25), 0.05, 0.6 / r))
        regimes.append(
            RegimeFriction(
                static_nm=tc * r * peak,
                coulomb_nm=tc * peak,
                alpha_s_rad=1.0 / (stribeck_speed * _log(rng, 0.8, 1.25)),
                viscous_scale=_log(rng, 0.8, 1.25),
                gain_scale=_log(rng, 0.8, 1.25),
            )
        )
    axis = Axis(inertia, eta, km, tuple(regimes))
    sensors = Sensors(
        gyro_noise_rad_s=_log(rng, 0.01, 0.1) * _DEG,
        gyro_averaged=True,
        resolver_bits=int(rng.integers(14, 20)),
    )
    effects: tuple[object, ...] = ()
    if name != "none":
        erng = np.random.default_rng([seed, attempt, 1 + EFFECT_NAMES.index(name)])
        effects = (_draw_effect(name, erng, axis, sensors, peak),)
    return DrawnAxis(seed, name, attempt, axis, effects, sensors, peak)


def _sign(rng: np.random.Generator) -> float:
    return 1.0 if rng.random() < 0.5 else -1.0


def _draw_effect(
    name: str, rng: np.random.Generator, axis: Axis, sensors: Sensors, peak: float
) -> object:
    j = axis.inertia_kg_m2
    if name == "cogging":
        return fx.Cogging(
            amplitude_nm=rng.uniform(0.03, 0.15) * peak,
            period_rad=2.0 * math.pi / int(rng.integers(24, 181)),
            phase_rad=rng.uniform(-math.pi, math.pi),
        )
    if name == "cable_spring":
        return fx.CableSpring(
            stiffness_nm_rad=rng.uniform(0.05, 0.3) * peak / (20.0 * _DEG),
            centre_rad=rng.uniform(-10.0, 10.0) * _DEG,
        )
    if name == "unbalance":
        return fx.Unbalance(
            amplitude_nm=rng.uniform(0.05, 0.3) * peak, phase_rad=rng.uniform(-math.pi, math.pi)
        )
    if name == "torque_offset":
        return fx.TorqueOffset(torque_offset_nm=_sign(rng) * rng.uniform(0.05, 0.2) * peak)
    if name == "input_delay":
        return fx.InputDelay(delay_s=int(rng.integers(10, 101)) * _STEP_S)
    if name == "deadzone":
        return fx.Deadzone(width_digits=rng.uniform(0.05, 0.2) * COMMAND_SCALE_DIGITS)
    if name == "saturation":
        return fx.Saturation(limit_digits=rng.uniform(0.55, 0.85) * COMMAND_SCALE_DIGITS)
    if name == "sensor_bias":
        return fx.GyroError(
            bias_rad_s=_sign(rng) * rng.uniform(5.0, 20.0) * sensors.gyro_noise_rad_s,
            scale=_sign(rng) * rng.uniform(0.005, 0.03),
        )
    if name == "resonance":
        fraction = rng.uniform(0.05, 0.3)
        j2 = fraction * j
        wn = 2.0 * math.pi * _log(rng, 15.0, 80.0)
        k = j2 * wn * wn
        return fx.PayloadMode(
            payload_fraction=fraction,
            stiffness_nm_rad=k,
            damping_nm_s_rad=2.0 * rng.uniform(0.01, 0.08) * math.sqrt(k * j2),
        )
    if name == "lugre":
        zmax = _log(rng, 2e-4, 5e-3)
        return fx.Bristles(
            stiffness_nm_rad=rng.uniform(0.05, 0.2) * peak / zmax, presliding_rad=zmax
        )
    raise AssertionError(name)  # EFFECT_TYPES and this function list the same names
