"""Seeded synthetic open-loop runs with a known extra effect (for tests and benchmarks).

The command is two random sines (a slow one that swings the axis over a wide
angle, a fast one that reverses it often) plus random steps, so that every
regime is visited, the axis sticks and breaks away, and it brakes against the
command. Strengths of each effect are drawn from ranges that are physically
plausible for the paper's inner azimuth axis (its Coulomb friction is 10 to
30 rad/s^2 of deceleration), see `EFFECT_RANGES`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from isp_twin.identification.measured import MeasuredData
from isp_twin.model.axis_model import simulate
from isp_twin.model.effects import make_effect
from isp_twin.model.parameters import EffectSpec, RateParams

__all__ = ["EFFECT_RANGES", "excitation", "make_run", "random_effect"]

#: Effect -> parameter -> (low, high, random sign?) of the true value.
EFFECT_RANGES: dict[str, dict[str, tuple[float, float, bool]]] = {
    "torque_offset": {"accel_rad_s2": (3.0, 8.0, True)},
    "cable_spring": {"stiffness_1_s2": (10.0, 30.0, False), "offset_rad_s2": (1.0, 4.0, True)},
    "unbalance": {"amplitude_rad_s2": (4.0, 10.0, False), "phase_rad": (-np.pi, np.pi, False)},
    # 24 to 72 cogging periods per turn.
    "cogging": {
        "amplitude_rad_s2": (2.0, 6.0, False),
        "period_rad": (2 * np.pi / 72, 2 * np.pi / 24, False),
        "phase_rad": (-np.pi, np.pi, False),
    },
    "input_delay": {"delay_s": (0.002, 0.010, False)},
    "deadzone": {"width_digits": (150.0, 400.0, False)},
    # Fraction of the largest command (made absolute by `random_effect`).
    "saturation": {"limit_digits": (0.6, 0.85, False)},
    "sensor_bias": {"bias_rad_s": (0.005, 0.02, True), "scale": (0.01, 0.05, True)},
    "lugre": {"accel_rad_s2": (8.0, 20.0, False), "presliding_rad": (1e-3, 5e-3, False)},
    # No payload_fraction: 0 (`Resonance.defaults`), gyro-only; the runs are
    # Eq. 6's (`make_run`), which a payload fraction does not change.
    "resonance": {
        "freq_hz": (20.0, 120.0, False),
        "damping_ratio": (0.02, 0.08, False),
        "coupling": (0.05, 0.2, True),
    },
}


def excitation(rng: np.random.Generator, n: int, dt: float) -> np.ndarray:
    """A random command [digits], shape (n,) (see module doc; levels suit Table 2's inner azimuth)."""
    t = np.arange(n) * dt
    slow = rng.uniform(1500.0, 3000.0) * np.sin(
        2 * np.pi * rng.uniform(0.4, 0.8) * t + rng.uniform(0, 2 * np.pi)
    )
    fast = rng.uniform(300.0, 800.0) * np.sin(
        2 * np.pi * rng.uniform(2.0, 6.0) * t + rng.uniform(0, 2 * np.pi)
    )
    steps = np.zeros(n)
    k = 0
    while k < n:
        length = int(rng.integers(int(0.05 / dt), int(0.3 / dt)))
        steps[k : k + length] = rng.uniform(-600.0, 600.0)
        k += length
    return slow + fast + steps


def random_effect(name: str, rng: np.random.Generator, u: np.ndarray | None = None) -> EffectSpec:
    """An effect of the library with random, physically plausible parameters."""
    params = {}
    for p, (lo, hi, signed) in EFFECT_RANGES[name].items():
        v = rng.uniform(lo, hi)
        if signed and rng.random() < 0.5:
            v = -v
        params[p] = float(v)
    if name == "saturation":
        params["limit_digits"] *= float(np.max(np.abs(u))) if u is not None else 3000.0
    return EffectSpec(name, params)


def make_run(
    name: str,
    rate: RateParams,
    u: np.ndarray,
    dt: float,
    rng: np.random.Generator,
    effects: Sequence[EffectSpec] = (),
    noise_rad_s: float = 0.003,
    angle_lsb_rad: float = 2 * np.pi / 2**20,
    angle0: float = 0.0,
) -> MeasuredData:
    """Simulate one run of the fast model with `effects` and add sensor noise.

    Args:
        name: run name.
        rate: the true rate-form parameters (4,).
        u: command [digits], (N,).
        dt: sample period [s].
        rng: noise source.
        effects: the true extra effects.
        noise_rad_s: gyro white-noise standard deviation [rad/s].
        angle_lsb_rad: angle-sensor resolution [rad] (a 20-bit encoder by
            default): the angle is rounded to it.
        angle0: initial angle [rad].
    """
    resp = simulate(rate, u, dt, angle0=angle0, effects=[make_effect(e, dt) for e in effects])
    n = u.shape[0]
    return MeasuredData(
        name=name,
        t=np.arange(n) * dt,
        u=np.asarray(u, float),
        omega=resp.omega + rng.normal(0.0, noise_rad_s, n),
        angle=np.round(resp.angle / angle_lsb_rad) * angle_lsb_rad
        if angle_lsb_rad > 0
        else resp.angle,
        source=None,
        dt=dt,
    )
