"""The reference axis: continuous-time physics, its integrator and stick logic.

One gimbal axis in continuous time, written independently of the project's
Eq. 6 model (`isp_twin.model.axis_model`), so that fitting that model to these data
is a test of the fit and not of the code that made the data::

    J1 dw/dt = Km_r u_amp(t) - eta_r w - F_r(w) - T_bristle + T_effects(theta) + T_payload

* ``F_r`` is the improved Stribeck law (the paper's Eq. 5) with its own
  Ts, Tc, alpha in each of the four regimes r = (side of the angle: R theta > 0,
  L theta <= 0) x (direction of motion), and per-regime multipliers of the
  viscous coefficient and of the motor gain (the paper's Table 2 differs per
  regime in every parameter).
* Stick: a Karnopp band. The rate is held at exactly 0 (the band) while the
  net drive ``|Km_r u + T_effects|`` does not exceed Ts of the regime it pushes
  towards; friction then equals the drive. A step that would carry the rate
  through zero ends at zero (the crossing instant is interpolated), so the band
  can never be jumped over; the next step decides breakaway or stick again.
* Integration: ``substeps`` steps per sample (default 10 -> 10 kHz at 1 ms),
  the command held over each sample (zero-order hold). Over one step the
  friction, effect and payload torques are frozen and the linear part
  ``J1 dw/dt = D - eta w`` is solved exactly (exponential integrator), angle
  included; a linear axis without friction is therefore exact at any step.
  The loop is compiled with numba (`_integrate`, scalar code in the order of
  this text; docs/reference_simulator.md "Independence").
* Payload resonance (`PayloadMode`): a second inertia J2 on a spring-damper;
  its deflection is integrated with semi-implicit Euler (stable and with
  negligible frequency error for ``omega_n * h << 1``).
* Sensors: the gyro (on the payload) reads the rate averaged over the sample
  just ended, i.e. exactly ``(theta2[k] - theta2[k-1]) / T`` (option: the point
  value at the sample instant), then scale/bias effects and white noise; the
  resolver (on the motor side) reads the angle at the sample instant, plus
  optional white noise, quantized to ``2 pi / 2**bits``.

Sample k of a run holds t_k = k T, the command u[k] applied over
[t_k, t_k+1), the gyro reading over [t_k-1, t_k] and the angle at t_k.
Units: SI inside (rad, rad/s, N·m, kg·m^2); the command in amplifier digits.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from isp_twin.errors import ParameterError, SimulationDiverged
from isp_twin.reference import effects as fx

__all__ = [
    "REGIME_NAMES",
    "RegimeFriction",
    "Axis",
    "Sensors",
    "ReferenceRun",
    "simulate",
]

#: Regime order: R = angle > 0, L = angle <= 0; + / - = direction of motion.
#: (The paper's order, written here again on purpose: no shared code.)
REGIME_NAMES: tuple[str, ...] = ("R+", "R-", "L+", "L-")

#: A rate above this [rad/s] is a runaway simulation (about 57000 deg/s).
_RUNAWAY_RAD_S = 1000.0


@dataclass(frozen=True)
class RegimeFriction:
    """Friction and per-regime multipliers of one regime.

    Attributes:
        static_nm: Ts, breakaway torque [N·m] (> 0).
        coulomb_nm: Tc, sliding torque at high speed [N·m] (0 < Tc <= Ts).
        alpha_s_rad: Stribeck decay factor [s/rad]: ``F = Tc + (Ts - Tc) exp(-alpha |w|)``.
        viscous_scale: multiplier of the axis's viscous coefficient [1].
        gain_scale: multiplier of the axis's motor gain [1].
    """

    static_nm: float
    coulomb_nm: float
    alpha_s_rad: float
    viscous_scale: float = 1.0
    gain_scale: float = 1.0


@dataclass(frozen=True)
class Axis:
    """The rigid axis and its friction.

    Attributes:
        inertia_kg_m2: J, total inertia of the axis [kg·m^2] (with a
            `PayloadMode`, J1 = J - J2 is the motor side).
        viscous_nm_s: eta, viscous coefficient [N·m·s/rad] (> 0).
        motor_gain_nm_per_digit: Km, amplifier and motor gain [N·m/digit].
        regimes: four `RegimeFriction`, order `REGIME_NAMES`.
    """

    inertia_kg_m2: float
    viscous_nm_s: float
    motor_gain_nm_per_digit: float
    regimes: tuple[RegimeFriction, ...]

    def __post_init__(self) -> None:
        if len(self.regimes) != 4:
            raise ParameterError(f"reference axis: 4 regimes needed, got {len(self.regimes)}")
        if min(self.inertia_kg_m2, self.viscous_nm_s) <= 0.0:
            raise ParameterError("reference axis: inertia and viscous coefficient must be > 0")
        for name, r in zip(REGIME_NAMES, self.regimes):
            if not 0.0 <= r.coulomb_nm <= r.static_nm or r.alpha_s_rad < 0.0:
                raise ParameterError(
                    f"reference axis regime {name}: needs 0 <= Tc <= Ts and alpha >= 0, got "
                    f"Tc={r.coulomb_nm}, Ts={r.static_nm}, alpha={r.alpha_s_rad}"
                )

    @property
    def time_constant_s(self) -> float:
        """Mechanical time constant J/eta [s] (before per-regime multipliers)."""
        return self.inertia_kg_m2 / self.viscous_nm_s


@dataclass(frozen=True)
class Sensors:
    """The gyro and the resolver.

    Attributes:
        gyro_noise_rad_s: white noise of the gyro, 1 sigma [rad/s].
        gyro_averaged: True: the rate averaged over the sample; False: its
            value at the sample instant.
        resolver_bits: quantization, bits per turn (None: no quantization).
        resolver_noise_rad: white noise of the resolver before quantization,
            1 sigma [rad].
    """

    gyro_noise_rad_s: float = 0.0
    gyro_averaged: bool = True
    resolver_bits: int | None = None
    resolver_noise_rad: float = 0.0

    @property
    def resolver_lsb_rad(self) -> float:
        """One resolver count [rad] (0 without quantization)."""
        return 0.0 if self.resolver_bits is None else 2.0 * math.pi / 2.0**self.resolver_bits


@dataclass(frozen=True)
class ReferenceRun:
    """One simulated open-loop run. Arrays shape (n,), SI; u in digits.

    Attributes:
        t: sample instants [s].
        u: command [digits], held over each sample.
        omega: gyro reading [rad/s] (effects and noise included).
        omega_clean: gyro reading without noise [rad/s].
        theta: resolver reading [rad] (noise and quantization included).
        rate: true motor-side rate at t_k [rad/s].
        angle: true motor-side angle at t_k [rad].
        regime: index into `REGIME_NAMES` of the motion at t_k, -1 at rest.
    """

    t: np.ndarray
    u: np.ndarray
    omega: np.ndarray
    omega_clean: np.ndarray
    theta: np.ndarray
    rate: np.ndarray
    angle: np.ndarray
    regime: np.ndarray

    def moving_per_regime(self) -> np.ndarray:
        """Number of samples in motion in each regime, shape (4,)."""
        return np.bincount(self.regime[self.regime >= 0], minlength=4)


def simulate(
    axis: Axis,
    u_digits: np.ndarray,
    effects: Sequence[object] = (),
    sensors: Sensors = Sensors(),
    *,
    dt: float = 1e-3,
    substeps: int = 10,
    theta0_rad: float = 0.0,
    seed: int | None = 0,
) -> ReferenceRun:
    """Simulate the axis for the command ``u_digits`` (shape (n,), held per sample).

    Args:
        axis: the axis.
        u_digits: command [digits], u[k] applied over [k dt, (k+1) dt).
        effects: objects from `isp_twin.reference.effects` (at most one of
            each kind of state effect: payload mode, bristles).
        sensors: gyro and resolver.
        dt: sample period [s].
        substeps: integration steps per sample.
        theta0_rad: angle at t = 0 [rad]; the axis starts at rest.
        seed: seed of the sensor noise (None: no noise at all).

    Raises:
        ParameterError: bad dt/substeps or an unknown effect object.
        SimulationDiverged: non-finite or runaway rate.
    """
    if dt <= 0.0 or substeps < 1:
        raise ParameterError(
            f"reference simulate: needs dt > 0 and substeps >= 1, got {dt}, {substeps}"
        )
    u = np.asarray(u_digits, dtype=float)
    if u.ndim != 1 or not np.all(np.isfinite(u)):
        bad = np.flatnonzero(~np.isfinite(u.ravel()))
        where = f"non-finite at sample {bad[0]}" if bad.size else f"shape {u.shape}"
        raise ParameterError(f"reference simulate: the command must be finite, shape (n,): {where}")
    n = u.shape[0]
    h = dt / substeps
    kinds = _Kinds(effects)
    out = np.empty((4, n))  # rate, angle, payload angle, payload rate at t_k
    regime = np.empty(n, dtype=np.intp)
    stop, w = _integrate(
        _amplifier_input(u, kinds, substeps, h),
        substeps,
        h,
        *_axis_arrays(axis, kinds.payload, h),
        *_torque_table(kinds.torques),
        *_state_effects(axis, kinds),
        float(theta0_rad),
        out,
        regime,
    )
    if stop >= 0:
        raise SimulationDiverged(
            f"reference simulation diverged at sample {stop} (rate {w:.3g} rad/s)"
        )
    return _read_sensors(out, regime, u, kinds.gyro_errors, sensors, dt, seed)


class _Kinds:
    """The effects of a run sorted by how the integrator applies them (`fx` module doc)."""

    def __init__(self, effects: Sequence[object]):
        self.delays, self.amplifiers, self.torques, self.gyro_errors = [], [], [], []
        self.payload = self.bristles = None
        for e in effects:
            if isinstance(e, fx.InputDelay):
                self.delays.append(e)
            elif isinstance(e, fx.PayloadMode):
                self.payload = e
            elif isinstance(e, fx.Bristles):
                self.bristles = e
            elif isinstance(e, fx.GyroError):
                self.gyro_errors.append(e)
            elif isinstance(e, (fx.Deadzone, fx.Saturation)):
                self.amplifiers.append(e)  # after the delay, in the order given
            elif isinstance(e, _TORQUE_KINDS):
                self.torques.append(e)
            else:
                raise ParameterError(f"reference simulate: unknown effect {e!r}")


#: Angle torques, by their code in the integrator's table (`_torque_table`).
_TORQUE_KINDS = (fx.Cogging, fx.CableSpring, fx.Unbalance, fx.TorqueOffset)


def _amplifier_input(u: np.ndarray, kinds: _Kinds, substeps: int, h: float) -> np.ndarray:
    """The amplifier's input on the integration grid: transport delay, then
    the amplifier's static maps (dead zone, saturation)."""
    n = u.shape[0]
    u_fine = np.repeat(u, substeps)
    for e in kinds.delays:
        shift = e.steps(h)
        if shift > 0:
            u_fine = np.concatenate([np.full(shift, u[0]), u_fine[:-shift]])[: n * substeps]
    for e in kinds.amplifiers:
        u_fine = e.amplify(u_fine)
    return u_fine


def _axis_arrays(axis: Axis, payload, h: float) -> tuple:
    """(J1, per-regime Ts, Tc, alpha, Km, eta, the decay over a step and the
    angle travelled per unit (w - w_inf) over one, (1 - decay) J1 / eta)."""
    j1 = axis.inertia_kg_m2
    if payload is not None:
        j1 -= payload.payload_fraction * axis.inertia_kg_m2
    regs = axis.regimes
    eta = [axis.viscous_nm_s * r.viscous_scale for r in regs]
    decay = [math.exp(-h * e / j1) for e in eta]
    reach_h = [(1.0 - d) * j1 / e for d, e in zip(decay, eta)]
    columns = (
        [r.static_nm for r in regs],
        [r.coulomb_nm for r in regs],
        [r.alpha_s_rad for r in regs],
        [axis.motor_gain_nm_per_digit * r.gain_scale for r in regs],
        eta,
        decay,
        reach_h,
    )
    return (j1, *(np.array(c, dtype=float) for c in columns))


def _torque_table(torques: Sequence[object]) -> tuple[np.ndarray, np.ndarray]:
    """(codes, parameters): each angle torque as its index in `_TORQUE_KINDS`
    and up to three parameters (`_angle_torque`)."""
    codes = np.empty(len(torques), dtype=np.int64)
    table = np.zeros((len(torques), 3))
    for i, e in enumerate(torques):
        codes[i] = next(c for c, kind in enumerate(_TORQUE_KINDS) if isinstance(e, kind))
        if isinstance(e, fx.Cogging):
            table[i] = e.amplitude_nm, e.period_rad, e.phase_rad
        elif isinstance(e, fx.CableSpring):
            table[i, :2] = e.stiffness_nm_rad, e.centre_rad
        elif isinstance(e, fx.Unbalance):
            table[i, :2] = e.amplitude_nm, e.phase_rad
        else:
            table[i, 0] = e.torque_offset_nm
    return codes, table


def _state_effects(axis: Axis, kinds: _Kinds) -> tuple:
    """The payload mode's (on, k, c, k/J2, c/J2, its two roots) and the
    bristles' (on, sigma0, z_max)."""
    payload, bristles = kinds.payload, kinds.bristles
    if payload is not None:
        j2 = payload.payload_fraction * axis.inertia_kg_m2
        kp, cp = payload.stiffness_nm_rad, payload.damping_nm_s_rad
        pa, pb = kp / j2, cp / j2
    else:
        kp = cp = 0.0
        pa, pb = 1.0, 0.0
    # The payload's deflection (x, x') is linear, x'' = -a x - b x' - w1':
    # stepped exactly for an axis acceleration w1' held over the step, with
    # the closed form of expm for the 2x2 mode (Sylvester, its two roots).
    disc = cmath.sqrt(pb * pb - 4.0 * pa)
    if abs(disc) < 1e-9 * math.sqrt(pa):  # repeated roots: nudge them apart
        disc = 1e-9 * math.sqrt(pa)
    root1, root2 = 0.5 * (-pb + disc), 0.5 * (-pb - disc)
    if bristles is not None:
        sigma0, zmax = bristles.stiffness_nm_rad, bristles.presliding_rad
    else:
        sigma0, zmax = 0.0, 1.0
    on = payload is not None
    return on, kp, cp, pa, pb, complex(root1), complex(root2), bristles is not None, sigma0, zmax


def _read_sensors(out, regime, u, gyro_errors, sensors: Sensors, dt: float, seed) -> ReferenceRun:
    """The run as the sensors read it from the integrated states ``out``
    (rate, angle, payload angle, payload rate at the sample instants)."""
    n = u.shape[0]
    rate, angle, payload_angle, payload_rate = out
    # Gyro on the payload: the rate averaged over the sample just ended is
    # exactly the payload angle's increment over the sample.
    if sensors.gyro_averaged:
        omega_clean = np.empty(n)
        omega_clean[0] = 0.0
        omega_clean[1:] = np.diff(payload_angle) / dt
    else:
        omega_clean = payload_rate.copy()
    for e in gyro_errors:
        omega_clean = e.read(omega_clean)
    rng = np.random.default_rng(seed) if seed is not None else None
    omega = omega_clean.copy()
    theta = angle.copy()
    if rng is not None:
        omega = omega + sensors.gyro_noise_rad_s * rng.standard_normal(n)
        if sensors.resolver_noise_rad > 0.0:
            theta = theta + sensors.resolver_noise_rad * rng.standard_normal(n)
    lsb = sensors.resolver_lsb_rad
    if lsb > 0.0:
        theta = np.round(theta / lsb) * lsb
    return ReferenceRun(
        t=np.arange(n) * dt,
        u=u.copy(),
        omega=omega,
        omega_clean=omega_clean,
        theta=theta,
        rate=rate,
        angle=angle,
        regime=regime,
    )


# ---------------------------------------------------------------- the integrator
# Compiled with numba: a loop over samples, sub-steps and the events inside a
# sub-step that numpy cannot vectorize along time. Written as plain scalar
# code, in the order of the physics above; `tests/test_reference_physics.py`
# checks it against closed forms.

#: The smallest positive angle: where a step lands on the boundary moving
#: towards R (theta > 0), so that the next step is on the side it moves to.
_ABOVE_ZERO = math.nextafter(0.0, 1.0)


@njit(cache=True, nogil=True)
def _angle_torque(codes, table, theta):  # pragma: no cover - compiled
    """The sum of the angle torques at ``theta`` [N·m] (`_torque_table`), each
    the physics of its class in `isp_twin.reference.effects`."""
    total = 0.0
    for i in range(codes.shape[0]):
        c = codes[i]
        if c == 0:  # Cogging
            total += table[i, 0] * math.sin(2.0 * math.pi * theta / table[i, 1] + table[i, 2])
        elif c == 1:  # CableSpring
            total += -table[i, 0] * (theta - table[i, 1])
        elif c == 2:  # Unbalance
            total += table[i, 0] * math.sin(theta + table[i, 1])
        else:  # TorqueOffset
            total += table[i, 0]
    return total


@njit(cache=True, nogil=True)
def _mode_step(x, xd, span, accel, pa, pb, root1, root2):  # pragma: no cover - compiled
    """The payload's deflection (x, x') after ``span`` [s] under an axis
    acceleration ``accel`` held over it: x'' = -a x - b x' - accel, the
    closed form of expm of the 2x2 mode (Sylvester, its two roots)."""
    e1, e2 = cmath.exp(root1 * span), cmath.exp(root2 * span)
    c0 = ((root1 * e2 - root2 * e1) / (root1 - root2)).real
    c1 = ((e1 - e2) / (root1 - root2)).real
    p00, p01, p10, p11 = c0, c1, -pa * c1, c0 - pb * c1
    # Input column A^-1 (Phi - I) (0, -1), A^-1 = [[-b, -1], [a, 0]] / a.
    v0, v1 = -p01, -(p11 - 1.0)
    g0, g1 = (-pb * v0 - v1) / pa, v0
    return p00 * x + p01 * xd + g0 * accel, p10 * x + p11 * xd + g1 * accel


@njit(cache=True, nogil=True)
def _integrate(
    u_fine, substeps, h, j1, ts, tc, al, km, eta, decay, reach_h, codes, table,
    has_payload, kp, cp, pa, pb, root1, root2, has_bristles, sigma0, zmax, theta0, out, regime,
):  # fmt: skip  # pragma: no cover - compiled
    """Integrate the axis over ``regime.size`` samples (module doc, "Stick" and
    "Integration"), writing ``out`` (rate, angle, payload angle, payload rate
    at each sample instant) and ``regime``. Returns (-1, 0) or, at a runaway,
    (the sample, its rate)."""
    n = regime.shape[0]
    w = 0.0
    th = theta0
    z = 0.0  # bristle deflection [rad]
    x = 0.0  # payload deflection from the motor side [rad], its rate
    xd = 0.0
    torques = codes.shape[0] > 0
    for k in range(n):
        out[0, k], out[1, k] = w, th
        out[2, k], out[3, k] = th + x, w + xd
        side = 0 if th > 0.0 else 2
        regime[k] = -1 if w == 0.0 else side + (1 if w < 0.0 else 0)
        base = k * substeps
        for j in range(substeps):
            ua = u_fine[base + j]
            left = h  # time left in this step [s]
            for _ in range(4):  # events inside the step: a stop, a change of side
                ext = _angle_torque(codes, table, th) if torques else 0.0
                if has_payload:
                    ext += kp * x + cp * xd
                side = 0 if th > 0.0 else 2
                landed = False
                landing = 0.0
                if w == 0.0:
                    dp = km[side] * ua + ext
                    dm = km[side + 1] * ua + ext
                    if dp > ts[side]:
                        r, sgn, drive = side, 1.0, dp
                    elif dm < -ts[side + 1]:
                        r, sgn, drive = side + 1, -1.0, dm
                    else:  # stuck: friction equals the drive
                        break
                else:
                    sgn = 1.0 if w > 0.0 else -1.0
                    r = side + (1 if w < 0.0 else 0)
                    drive = km[r] * ua + ext
                if left == h:
                    e, reach = decay[r], reach_h[r]
                else:
                    e = math.exp(-left * eta[r] / j1)
                    reach = (1.0 - e) * j1 / eta[r]
                # Predictor with the torques at the start of the step; corrector
                # with friction at the mean rate, angle torques, payload and
                # bristles at mid-travel (second order where they are smooth).
                if w == 0.0:
                    friction = ts[r]
                else:
                    friction = tc[r] + (ts[r] - tc[r]) * math.exp(-al[r] * abs(w))
                w_inf = (drive - sgn * friction - sigma0 * z) / eta[r]
                w_new = w_inf + (w - w_inf) * e
                if w_new * sgn > 0.0:
                    half = 0.5 * (w_inf * left + (w - w_inf) * reach)
                    z_mid, drive_mid = z, drive
                    if has_bristles:
                        z_ss = zmax * sgn
                        z_mid = z_ss + (z - z_ss) * math.exp(-abs(half) / zmax)
                    if torques:
                        drive_mid += _angle_torque(codes, table, th + half) - _angle_torque(
                            codes, table, th
                        )
                    if has_payload:
                        xm, xdm = _mode_step(x, xd, 0.5 * left, (w_new - w) / left, pa, pb,
                                             root1, root2)  # fmt: skip
                        drive_mid += kp * (xm - x) + cp * (xdm - xd)
                    mean = 0.5 * (w + w_new)
                    friction = tc[r] + (ts[r] - tc[r]) * math.exp(-al[r] * abs(mean))
                    w_inf = (drive_mid - sgn * friction - sigma0 * z_mid) / eta[r]
                    w_new = w_inf + (w - w_inf) * e
                if w_new * sgn <= 0.0:
                    if w == 0.0:  # the bristles hold it: no breakaway after all
                        break
                    # Motion stops inside the step: end it at the crossing (the
                    # Karnopp band at 0); the rest of the step decides stick or reverse.
                    used = left * w / (w - w_new)
                    dth = 0.5 * w * used
                    w_new = 0.0
                else:
                    used = left
                    dth = w_inf * left + (w - w_inf) * reach
                    if (th > 0.0) != (th + dth > 0.0) and dth != 0.0:
                        # The angle changes side: end the step there (the
                        # regime, hence gain and friction, changes with it).
                        used = left * th / -dth
                        w_new = w_inf + (w - w_inf) * math.exp(-used * eta[r] / j1)
                        landed = True
                        landing = _ABOVE_ZERO if dth > 0.0 else 0.0
                        dth = landing - th
                if has_bristles:
                    # dz/dtheta = 1 - sign(w) z / zmax: exact over the travelled angle.
                    z_ss = zmax * sgn
                    z = z_ss + (z - z_ss) * math.exp(-abs(dth) / zmax)
                if has_payload and used > 0.0:
                    x, xd = _mode_step(x, xd, used, (w_new - w) / used, pa, pb, root1, root2)
                w = w_new
                th = landing if landed else th + dth
                left -= used
                if left <= 1e-12 * h:
                    left = 0.0
                    break
            if has_payload and left > 0.0:  # the payload rings on a stuck axis
                x, xd = _mode_step(x, xd, left, 0.0, pa, pb, root1, root2)
        if not (abs(w) < _RUNAWAY_RAD_S and math.isfinite(th)):
            return k, w
    return -1, 0.0
