"""The paper's open-loop identification experiments, generated from a model.

Eq. 7 drives one gimbal open loop with
``u = amplitude*cos(2*pi*f*t) + offset`` digits (950, 0.5 Hz, -200 digits,
2000 samples at 1 ms) and records the gyro rate and the resolver angle. Here
the run is simulated with known parameters and written in the measured-data
format (`isp_twin.identification.measured`), with realistic sensor errors:

* gyro: white noise of `gyro_noise_deg_s` (1 sigma) on the rate;
* resolver: the angle rounded to `resolver_lsb_deg` (16 bit per turn by default).

The exact Eq. 7 input, started at 0 deg, drives the inner azimuth axis of
Table 2 into its -4 deg stop after about 1 s (the L- regime is fast), and data
at a stop is not described by Eq. 6. `PAPER_SET` therefore holds four
variations (amplitude, offset, start angle, frequency) chosen by simulating
Table 2 so that the angle stays inside +-3.9 deg and each of the four regimes
is visited by at least 120 moving samples in every set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from isp_twin.errors import ParameterError
from isp_twin.experiments.open_loop import OpenLoopResponse, simulate_open_loop
from isp_twin.identification.measured import MIN_SAMPLES, MeasuredData
from isp_twin.model.parameters import ParameterSet
from isp_twin.units import DEG
from isp_twin.vocabulary import GIMBAL_AXES

__all__ = [
    "Excitation",
    "PAPER_SET",
    "INNER_EL_SET",
    "paper_set",
    "EQ7",
    "GYRO_NOISE_DEG_S",
    "RESOLVER_LSB_DEG",
    "INNER_STOP_DEG",
    "generate_openloop",
    "generate_set",
]

#: Gyro rate noise, 1 sigma [deg/s]: a tactical-grade FOG at 1 kHz (assumption).
GYRO_NOISE_DEG_S = 0.02
#: Resolver resolution [deg]: 16 bit per turn.
RESOLVER_LSB_DEG = 360.0 / 2**16
#: The inner gimbals' hard stops [deg] (the paper's +-4 deg inner travel).
INNER_STOP_DEG = 4.0


@dataclass(frozen=True)
class Excitation:
    """One open-loop run: ``u = amplitude*cos(2*pi*freq*t) + offset`` [digits].

    Attributes:
        amplitude_digits: cosine amplitude [digits].
        freq_hz: frequency [Hz].
        offset_digits: constant offset [digits].
        initial_angle_deg: gimbal angle at t = 0 [deg].
        n_samples: number of samples.
        dt: sample period [s].
        name: label, used as the file stem.
    """

    amplitude_digits: float = 950.0
    freq_hz: float = 0.5
    offset_digits: float = -200.0
    initial_angle_deg: float = 0.0
    n_samples: int = 2000
    dt: float = 1e-3
    name: str = "eq7"

    def command(self) -> tuple[np.ndarray, np.ndarray]:
        """(t [s], u [digits]), shape (n_samples,)."""
        t = np.arange(self.n_samples) * self.dt
        u = self.amplitude_digits * np.cos(2 * math.pi * self.freq_hz * t) + self.offset_digits
        return t, u


#: The exact input of Eq. 7.
EQ7 = Excitation()
#: Four variations of Eq. 7 that visit all regimes without reaching a stop
#: (see module docstring; chosen for the inner azimuth axis of Table 2).
PAPER_SET: tuple[Excitation, ...] = (
    Excitation(750, 0.5, 0, -3.0, name="set1_a750_f0.5_y-3"),
    Excitation(750, 0.5, -100, 1.5, name="set2_a750_o-100_y1.5"),
    Excitation(750, 1.0, 0, -3.0, name="set3_a750_f1_y-3"),
    Excitation(950, 0.5, 0, -1.5, name="set4_a950_f0.5_y-1.5"),
)


#: The same for the inner elevation axis of paper_table2.yaml (an assumption:
#: mirrored half-planes, so it drifts the other way and `PAPER_SET` drives it
#: into its stops); chosen the same way, by simulating that axis.
INNER_EL_SET: tuple[Excitation, ...] = (
    Excitation(650, 0.5, 0, -1.5, name="el1_a650_f0.5_y-1.5"),
    Excitation(950, 1.0, -100, -1.5, name="el2_a950_f1_o-100_y-1.5"),
    Excitation(650, 1.0, -100, 0.0, name="el3_a650_f1_o-100_y0"),
    Excitation(850, 1.0, 0, -3.0, name="el4_a850_f1_y-3"),
)


def paper_set(axis: str) -> tuple[Excitation, ...]:
    """The four Eq. 7 variations for `axis` (`INNER_EL_SET` for inner_el, else `PAPER_SET`)."""
    return INNER_EL_SET if axis == "inner_el" else PAPER_SET


def _stop_rad(axis: str) -> float | None:
    return INNER_STOP_DEG * DEG if axis.startswith("inner") else None


#: Ranges of the generator's settings: (low, high, low allowed, high allowed),
#: those of the scenario schema's open-loop command (every value finite,
#: frequency below the Nyquist limit of the 1 kHz sample rate; a huge
#: amplitude is caught as divergence by the simulation).
_RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "amplitude_digits": (0.0, math.inf, True, False),
    "freq_hz": (0.0, math.inf, False, False),
    "offset_digits": (-math.inf, math.inf, False, False),
    "initial_angle_deg": (-180.0, 180.0, True, True),
    "gyro_noise_deg_s": (0.0, math.inf, True, False),
    "resolver_lsb_deg": (0.0, math.inf, True, False),
}
#: Largest run the generator writes [samples] (10^7: 2.8 h at 1 kHz).
MAX_SAMPLES = 10_000_000


def check_excitation(
    *,
    amplitude_digits: float,
    freq_hz: float,
    offset_digits: float,
    n_samples: int,
    initial_angle_deg: float,
    gyro_noise_deg_s: float,
    resolver_lsb_deg: float,
    seed: int,
) -> None:
    """Check a generator setting (finite, in range) before anything is simulated.

    Raises:
        ParameterError: naming the setting, its value and the allowed range.
    """
    values = {
        "amplitude_digits": amplitude_digits,
        "freq_hz": freq_hz,
        "offset_digits": offset_digits,
        "initial_angle_deg": initial_angle_deg,
        "gyro_noise_deg_s": gyro_noise_deg_s,
        "resolver_lsb_deg": resolver_lsb_deg,
    }
    for key, x in values.items():
        lo, hi, lo_ok, hi_ok = _RANGES[key]
        inside = (
            math.isfinite(x) and (lo <= x if lo_ok else lo < x) and (x <= hi if hi_ok else x < hi)
        )
        if not inside:
            lb, rb = "[" if lo_ok else "(", "]" if hi_ok else ")"
            raise ParameterError(f"{key}: {x} is outside {lb}{lo:g}, {hi:g}{rb}")
    if not MIN_SAMPLES <= n_samples <= MAX_SAMPLES:
        raise ParameterError(f"n_samples: {n_samples} is outside [{MIN_SAMPLES}, {MAX_SAMPLES}]")
    if seed < 0:
        raise ParameterError(f"seed: must be >= 0, got {seed}")


def generate_openloop(
    params: ParameterSet,
    axis: str = "inner_az",
    amplitude_digits: float = 950.0,
    freq_hz: float = 0.5,
    offset_digits: float = -200.0,
    n_samples: int = 2000,
    dt: float = 1e-3,
    gyro_noise_deg_s: float = GYRO_NOISE_DEG_S,
    resolver_lsb_deg: float = RESOLVER_LSB_DEG,
    seed: int = 0,
    engine: str = "fast",
    initial_angle_deg: float = 0.0,
    name: str = "eq7",
) -> MeasuredData:
    """Simulate one open-loop run (Eq. 7 by default) as measured data.

    Args:
        params: the true parameters.
        axis: gimbal axis (one of `GIMBAL_AXES`).
        amplitude_digits, freq_hz, offset_digits: the cosine input of Eq. 7.
        n_samples, dt: length and sample period [s]; dt must equal the
            parameter set's sample time (the parameters are per sample).
        gyro_noise_deg_s: white rate noise, 1 sigma [deg/s]; 0 for none.
        resolver_lsb_deg: angle quantization [deg]; 0 for none.
        seed: noise seed (same seed -> identical data).
        engine: "fast" (Eq. 6, `isp_twin.model.axis_model`) or "twin" (MuJoCo).
        initial_angle_deg: angle at t = 0 [deg].
        name: the run's name (file stem).

    Returns:
        `MeasuredData` with u in digits, SI rate and angle.
    """
    _check_axis_and_period(params, axis, dt)
    check_excitation(
        amplitude_digits=amplitude_digits,
        freq_hz=freq_hz,
        offset_digits=offset_digits,
        n_samples=n_samples,
        initial_angle_deg=initial_angle_deg,
        gyro_noise_deg_s=gyro_noise_deg_s,
        resolver_lsb_deg=resolver_lsb_deg,
        seed=seed,
    )
    _check_run_limits(axis, freq_hz, dt, initial_angle_deg, engine)
    # The open-loop experiment of Fig. 2 with Eq. 7's input; both engines
    # apply the parameter file's effects.
    response = simulate_open_loop(
        params,
        axis=axis,
        amplitude_digits=amplitude_digits,
        freq_hz=freq_hz,
        offset_digits=offset_digits,
        duration_s=(n_samples - 1) * dt,
        initial_angle_rad=initial_angle_deg * DEG,
        angle_limit_rad=_stop_rad(axis),
        engine=engine,
    )
    return _as_measured(response, name, dt, gyro_noise_deg_s, resolver_lsb_deg, seed)


def _check_axis_and_period(params: ParameterSet, axis: str, dt: float) -> None:
    """A known axis, and dt the parameters' sample time (they are per sample)."""
    if axis not in GIMBAL_AXES:
        raise ParameterError(f"axis '{axis}' unknown; allowed: {', '.join(GIMBAL_AXES)}")
    if not math.isclose(dt, params.sample_time_s, rel_tol=1e-9):
        raise ParameterError(
            f"dt {dt} s differs from the parameter set's sample_time_s {params.sample_time_s} s"
        )


def _check_run_limits(
    axis: str, freq_hz: float, dt: float, initial_angle_deg: float, engine: str
) -> None:
    """Below Nyquist, inside the axis's stops, a known engine."""
    if freq_hz >= 0.5 / dt:
        raise ParameterError(
            f"freq_hz: {freq_hz} is not below the Nyquist frequency {0.5 / dt:g} Hz of dt {dt} s"
        )
    if _stop_rad(axis) is not None and abs(initial_angle_deg) > INNER_STOP_DEG:
        raise ParameterError(
            f"initial_angle_deg: {initial_angle_deg} is beyond the {axis} stop "
            f"(|angle| <= {INNER_STOP_DEG:g} deg)"
        )
    if engine not in ("fast", "twin"):
        raise ParameterError(f"engine '{engine}' unknown; allowed: fast, twin")


def _as_measured(
    response: OpenLoopResponse,
    name: str,
    dt: float,
    gyro_noise_deg_s: float,
    resolver_lsb_deg: float,
    seed: int,
) -> MeasuredData:
    """The run as the sensors report it: the gyro's white noise on the rate, the
    resolver's quantization of the angle."""
    t, u, omega, angle = response.t, response.u, response.omega, response.angle
    rng = np.random.default_rng(seed)
    if gyro_noise_deg_s > 0:
        omega = omega + rng.normal(0.0, gyro_noise_deg_s * DEG, size=omega.shape)
    if resolver_lsb_deg > 0:
        lsb = resolver_lsb_deg * DEG
        angle = np.round(angle / lsb) * lsb
    return MeasuredData(name=name, t=t, u=u, omega=omega, angle=angle, source=None, dt=dt)


def generate_set(
    params: ParameterSet,
    axis: str = "inner_az",
    excitations: tuple[Excitation, ...] = PAPER_SET,
    gyro_noise_deg_s: float = GYRO_NOISE_DEG_S,
    resolver_lsb_deg: float = RESOLVER_LSB_DEG,
    seed: int = 0,
    engine: str = "fast",
) -> list[MeasuredData]:
    """Several runs (default `PAPER_SET`), run i with noise seed ``seed + i``."""
    return [
        generate_openloop(
            params,
            axis,
            e.amplitude_digits,
            e.freq_hz,
            e.offset_digits,
            e.n_samples,
            e.dt,
            gyro_noise_deg_s,
            resolver_lsb_deg,
            seed + i,
            engine,
            e.initial_angle_deg,
            e.name,
        )
        for i, e in enumerate(excitations)
    ]
