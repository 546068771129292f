"""The two-mass payload integrated in the sub-stepped model's sub-steps
(the library's `resonance` with a payload fraction, `isp_twin.model.substep_model`):
the free mode on a frictionless axis, the clamped mode on a stuck motor side,
and reference axes with the true payload held by the registered effect."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from isp_twin.estimation.simulation_error import resolver_sides
from isp_twin.identification.cost import rmse
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.model.effects.batched import make_batched
from isp_twin.model.effects.resonance import Resonance
from isp_twin.model.parameters import RATE_LAYOUT, EffectSpec, RateParams
from isp_twin.model.substep_model import (
    SIDE_FOLLOWS_GYRO,
    STATE_COLUMNS,
    _advance_rows,
    _substep_table,
)
from isp_twin.reference import design_experiment
from isp_twin.units import DEG

DT = 1e-3
M = 10


def _axis(pole, static) -> RateParams:
    ones = np.ones(4)
    return RateParams(pole * ones, 0 * ones, static * ones, 0.5 * static * ones, 0 * ones)


def _ring(params: RateParams, mode: dict, y0: float, n: int):
    """The kernel from rest with the payload deflected by y0: motor rate and y per sample."""
    effect = Resonance({"coupling": 1.0, **mode}, DT)
    cols = effect.substep_columns(DT, M)
    sfx = np.array([[0.0, 1.0, *(float(cols[c]) for c in STATE_COLUMNS[2:])]])
    kstate = np.array([[0.0, y0, 0.0]])
    table = _substep_table(params, 1, M)
    zeros = np.zeros((1, n))
    w, ang = np.zeros(1), np.full(1, 0.1)
    out = [np.zeros((1, n)) for _ in range(3)] + [np.zeros((1, n), dtype=np.int64)]
    y, yd = np.empty(n), np.zeros(n)
    y[0] = y0
    for k in range(1, n):
        _advance_rows(table, zeros, zeros, np.zeros((1, 1)), False, -1, k, k + 1, M, DT, True,
                      True, True, w, ang, *out, 0, 1, sfx, kstate)  # fmt: skip
        y[k], yd[k] = kstate[0, 1], kstate[0, 2]
    gyro = out[0][0]  # the payload's rate w1 + (1 + r) y'
    return gyro - (1.0 + cols["payload_ratio"]) * yd, y


def _frequency_hz(y: np.ndarray) -> float:
    """From the mean spacing of the zero crossings (upward)."""
    up = np.flatnonzero((y[:-1] < 0) & (y[1:] >= 0))
    frac = y[up] / (y[up] - y[up + 1])
    t = (up + frac) * DT
    return 1.0 / float(np.mean(np.diff(t)))


def test_a_frictionless_two_mass_axis_rings_at_the_free_frequency():
    # No friction, no viscous torque (a = 1): the mode is the free two-mass
    # mode sqrt(k/mu); with J2 = 0.4 J the clamped one is 22 % lower.
    mode = {"freq_hz": 40.0, "damping_ratio": 0.005, "payload_fraction": 0.4}
    _, y = _ring(_axis(1.0, 0.0), mode, 1e-3, 400)
    assert _frequency_hz(y) == pytest.approx(40.0 * math.sqrt(1 - 0.005**2), rel=0.01)


def test_a_stuck_motor_side_lets_the_payload_ring_at_the_clamped_frequency():
    # Breakaway far above the spring's pull: the motor side never moves, and
    # (1 + r) y'' + 2 zeta wn y' + wn^2 y = 0 is stepped exactly.
    f, zeta, fraction = 40.0, 0.02, 0.4
    r = fraction / (1 - fraction)
    mode = {"freq_hz": f, "damping_ratio": zeta, "payload_fraction": fraction}
    motor, y = _ring(_axis(math.exp(-DT / 0.05), 10.0), mode, 1e-3, 300)
    assert np.all(motor == 0.0)
    wc, zc = 2 * math.pi * f / math.sqrt(1 + r), zeta / math.sqrt(1 + r)
    wd = wc * math.sqrt(1 - zc**2)
    t = np.arange(300) * DT
    want = 1e-3 * np.exp(-zc * wc * t) * (np.cos(wd * t) + zc * wc / wd * np.sin(wd * t))
    assert np.allclose(y, want, rtol=0, atol=1e-9 * 1e-3)


def _run(params: RateParams, mode: dict, u, w0: float, n: int, m: int) -> np.ndarray:
    """The kernel from motor rate w0 under the command u (a constant or per
    sample): the gyro's point reading per sample and the motor rate at the end."""
    effect = Resonance({"coupling": 1.0, **mode}, DT)
    cols = effect.substep_columns(DT, m)
    sfx = np.array([[0.0, 1.0, *(float(cols[c]) for c in STATE_COLUMNS[2:])]])
    kstate = np.zeros((1, 3))
    table = _substep_table(params, 1, m)
    w, ang = np.full(1, w0), np.full(1, 0.1)
    out = [np.zeros((1, n)) for _ in range(3)] + [np.zeros((1, n), dtype=np.int64)]
    commands = np.broadcast_to(u, (1, n)).copy()
    _advance_rows(table, commands, np.zeros((1, n)), np.zeros((1, 1)), False, -1, 1, n,
                  m, DT, True, True, True, w, ang, *out, 0, 1, sfx, kstate)  # fmt: skip
    return out[0][0], w[0]


def test_a_viscous_two_mass_axis_follows_the_linear_solution_to_second_order():
    # No friction: the axis is linear, w' = -(w - r y')/tau + b u with
    # y'' + 2 zeta wn y' + wn^2 y = -w' (centre-of-mass form), and its step
    # response is exp(A t). The viscous torque acts on the motor side's rate
    # w - r y', which moves with the mode inside each sub-step: taken at the
    # sub-step's start it is a first-order error (0.12 % of the response at
    # m = 10), at the sub-step's mean rate a second-order one.
    tau, f, zeta, fraction, g, u = 0.01, 60.0, 0.02, 0.25, 1e-4, 100.0
    pole, r, wn = math.exp(-DT / tau), fraction / (1 - fraction), 2 * math.pi * f
    ones = np.ones(4)
    params = RateParams(pole * ones, g * ones, 0 * ones, 0 * ones, 0 * ones)
    b = g / ((1 - pole) * tau)
    a = np.array([[-1 / tau, 0, r / tau, b * u], [0, 0, 1, 0],
                  [1 / tau, -wn * wn, -2 * zeta * wn - r / tau, -b * u], [0, 0, 0, 0]])  # fmt: skip
    n = 200
    exact = np.array([expm(a * k * DT)[:, 3] for k in range(n)])
    gyro_exact = exact[:, 0] + exact[:, 2]  # w1 + (1 + r) y' = w + y'
    mode = {"freq_hz": f, "damping_ratio": zeta, "payload_fraction": fraction}
    errors = []
    for m in (10, 40):
        gyro, _ = _run(params, mode, u, 0.0, n, m)
        errors.append(np.max(np.abs(gyro[1:] - gyro_exact[1:])) / np.max(np.abs(gyro_exact)))
    assert errors[0] < 1e-4
    assert errors[0] / errors[1] > 10.0  # 16 for second order, 4 for first


def test_a_stop_of_a_two_mass_motor_side_is_split_inside_the_sub_step():
    # A coasting axis comes to rest under Coulomb friction; the payload rings
    # on. The sub-step in which the motor side stops is split at the stop
    # (the payload free up to it, clamped after), as the reference does, so
    # 10 sub-steps per sample agree with 1280 to a second-order error. Ended
    # at the sub-step's end the stop is late by up to one sub-step: 3e-4 of
    # the start rate.
    ones = np.ones(4)
    tc, w0 = 4e-4, 0.05
    params = RateParams(
        math.exp(-DT / 0.2) * ones, 1e-5 * ones, 1.5 * tc * ones, tc * ones, 50 * ones
    )
    mode = {"freq_hz": 40.0, "damping_ratio": 0.02, "payload_fraction": 0.3}
    fine, w_end = _run(params, mode, 0.0, w0, 300, 1280)
    assert w_end == 0.0, "the example must end with the motor side stuck"
    assert np.max(np.abs(fine[150:])) > 0.02 * w0, "and the payload ringing"
    coarse, _ = _run(params, mode, 0.0, w0, 300, 10)
    assert np.max(np.abs(coarse - fine)) < 1e-5 * w0


def test_stick_slip_pulled_by_the_payload_converges_with_the_sub_steps():
    # A slow sine command near the breakaway level: the motor side sticks and
    # slips, and some breakaways come from the spring's pull with the command
    # below the static level. The centre of mass then accelerates against
    # the motor side's motion; that is no bristle holding the axis. Held
    # back as one, the breakaway sub-step moved only by the mode: 7e-4 of
    # the peak rate off the sub-stepped limit at m = 10, first order.
    ones = np.ones(4)
    params = RateParams(math.exp(-DT / 0.11) * ones, 1e-5 * ones, 8e-4 * ones, 5e-4 * ones,
                        20.0 * ones)  # fmt: skip
    mode = {"freq_hz": 43.0, "damping_ratio": 0.024, "payload_fraction": 0.19}
    n = 1000
    u = 150.0 * np.sin(2 * np.pi * 2.0 * np.arange(n) * DT)
    fine = _run(params, mode, u, 0.0, n, 1280)[0]
    assert np.count_nonzero(fine == 0.0) > 20, "the example must stick"
    coarse = _run(params, mode, u, 0.0, n, 10)[0]
    assert np.max(np.abs(coarse - fine)) < 2e-5 * np.max(np.abs(fine))


@pytest.mark.parametrize("seed", [1000, 1001, 1002, 1003, 1004, 1009, 1014])
def test_the_true_two_mass_payload_of_reference_axes_is_within_the_issues_bound(seed):
    # Dev seeds of issue 8 (1000: 36 Hz, 1002); with the gyro-only form (f = 0) the
    # truth left 2.7 / 10.8 and 1.06 / 4.19 noise floors (train1 / held-out).
    # 1001, 1003 and 1004 held out: 2.11, 1.52 and 1.55 before the stop of a
    # two-mass motor side was split and its viscous torque taken at the
    # sub-step's mean rate (docs/diagnosis.md "Stop 30"). 1009 (17 Hz): 16.1
    # on train1 before the fused angle got back the payload's quasi-static
    # deflection its smoothing takes off (`Effect.fusion_gain`); 1014:
    # 6.98 on train1 before a breakaway pulled by the spring was let go.
    # The bound is the issue's 1.5 noise floors for an effect, not 1.
    # The reference's truth is in the registered `resonance`'s parameters.
    exp = design_experiment(seed, "resonance")
    truth = exp.truth()
    sigma = truth["noise_sigma_deg_s"] * DEG
    regimes = truth["rate_form"]["regimes"]
    x = np.concatenate([[regimes[r][f] for f in RATE_LAYOUT.fields] for r in truth["regime_order"]])
    spec = EffectSpec("resonance", truth["effects"][0]["params"])
    assert spec.params["payload_fraction"] == truth["effects"][0]["physical"]["payload_fraction"]
    for name in ("train1", "heldout"):
        r = exp.runs[name]
        data = [MeasuredData(name, r.t, r.u, r.omega, r.theta, None, DT)]
        error = rmse(RateParams.from_vector(x), data, effects=(spec,), timing=Timing(0.0, True))
        assert error / sigma < 1.5, name


def _crossing(side_y, use_side: int, mode: dict, n: int, known=None):
    """The kernel from rest at -0.5 deg, driven toward +, on an axis whose
    drive gain is 25 % higher on the right side: per sample the motor
    angle, the payload coordinate y and the motor rate (`known`: the
    resolver's sides, `_advance_rows`)."""
    effect = Resonance({"coupling": 1.0, **mode}, DT)
    cols = effect.substep_columns(DT, M)
    sfx = np.array([[0.0, 1.0, *(float(cols[c]) for c in STATE_COLUMNS[2:])]])
    kstate = np.zeros((1, 3))
    ones = np.ones(4)
    gain = np.array([1.25, 1.25, 1.0, 1.0]) * 2e-4  # R+, R-, L+, L-
    params = RateParams(0.97 * ones, gain, 0.01 * ones, 0.005 * ones, 5.0 * ones)
    table = _substep_table(params, 1, M)
    u = np.full((1, n), 400.0)
    w, ang = np.zeros(1), np.full(1, -0.5 * DEG)
    out = [np.zeros((1, n)) for _ in range(3)] + [np.zeros((1, n), dtype=np.int64)]
    angle, y, rate = np.full(n, ang[0]), np.zeros(n), np.zeros(n)
    for k in range(1, n):
        _advance_rows(table, u, np.zeros((1, n)), side_y, use_side, -1, k, k + 1, M, DT, True,
                      True, True, w, ang, *out, 0, 1, sfx, kstate, None, known)  # fmt: skip
        angle[k], y[k], rate[k] = ang[0], kstate[0, 1], w[0]
    return angle, y, rate, 1.0 + cols["payload_ratio"]


def test_the_side_of_a_two_mass_axis_is_the_motor_sides_when_the_angle_follows_the_payload():
    # The measured (fused) angle follows the gyro's integral, the payload's
    # angle, within the fusion's window: motor angle + (r + c) y. Fed that,
    # the kernel must switch sides where the motor side crosses 0 (its own
    # angle, `use_side` 0), not where the ringing payload does. A motor-side
    # angle (the raw resolver, `use_side` 1) is taken as it is.
    mode = {"freq_hz": 30.0, "damping_ratio": 0.02, "payload_fraction": 0.25}
    n = 120
    angle, y, rate, k = _crossing(np.zeros((1, 1)), 0, mode, n)
    assert angle[0] < 0.0 < angle[-1]
    payload_angle = (angle + k * y)[None, :]
    cross = np.flatnonzero(angle > 0)[0]
    assert (
        np.sign(payload_angle[0, cross - 3 : cross + 3]).tolist()
        != np.sign(angle[cross - 3 : cross + 3]).tolist()
    ), "the example must have the payload cross 0 at another sample"
    _, _, fused, _ = _crossing(payload_angle, SIDE_FOLLOWS_GYRO, mode, n)
    _, _, resolver, _ = _crossing(angle[None, :], 1, mode, n)
    # Linear interpolation of the angles inside a sample is all that
    # separates them: far under the 25 % drive step of a wrong side.
    for fed in (fused, resolver):
        assert np.max(np.abs(fed - rate)) < 1e-3 * np.max(np.abs(rate))


def test_the_resolver_keeps_the_side_it_settles_against_a_fused_angle_off_the_motor_side():
    # The model's own deflection taken off the fused angle leaves the side
    # to the model's ringing: off by 0.5 deg here (a fused angle ahead of
    # the motor side), it switched sides early. A resolver reading of one
    # sign at both ends of a step settles the side (`resolver_sides`); only
    # within its quantum of 0 (it reads 0) does the fused angle decide.
    mode = {"freq_hz": 30.0, "damping_ratio": 0.02, "payload_fraction": 0.25}
    n = 120
    angle, y, rate, k = _crossing(np.zeros((1, 1)), 0, mode, n)
    ahead = (angle + k * y + 0.5 * DEG)[None, :]
    quantum = 0.005 * DEG
    resolver = quantum * np.round(angle / quantum)
    known = resolver_sides(resolver)[None, :]
    _, _, early, _ = _crossing(ahead, SIDE_FOLLOWS_GYRO, mode, n)
    _, _, kept, _ = _crossing(ahead, SIDE_FOLLOWS_GYRO, mode, n, known)
    settled_left = np.flatnonzero(known[0] < 0)
    assert np.max(np.abs(early - rate)) > 0.05 * np.max(np.abs(rate)), "the example must go wrong"
    # Until the resolver reads 0 the side is the true one: the rates agree.
    upto = settled_left[-1] + 1
    assert np.max(np.abs(kept[:upto] - rate[:upto])) < 1e-3 * np.max(np.abs(rate))
    assert np.max(np.abs(kept - rate)) < 0.5 * np.max(np.abs(early - rate))


def test_resolver_sides_are_settled_only_by_readings_of_one_sign_at_both_ends():
    angle = np.array([-2.0, -1.0, 0.0, 1.0, 2.0, 2.0, -1.0, -1.0])
    assert resolver_sides(angle).tolist() == [-1, 0, 0, 1, 1, 0, -1, 0]


def test_the_fusions_deflection_is_the_modes_quasi_static_one():
    # Under a constant acceleration the mode settles at y = -w'/wn^2; the
    # gyro's integral then runs (r + c) y ahead of the motor side, which
    # the fusion's moving average keeps out. `fusion_gain` gives it
    # back: equal to the kernel's own settled deflection under that drive.
    mode = {"freq_hz": 25.0, "damping_ratio": 0.3, "payload_fraction": 0.2}
    ones = np.ones(4)
    params = RateParams(ones, 2e-5 * ones, 0 * ones, 0 * ones, 0 * ones)
    u, n = 50.0, 400
    effect = Resonance({"coupling": 1.0, **mode}, DT)
    cols = effect.substep_columns(DT, M)
    sfx = np.array([[0.0, 1.0, *(float(cols[c]) for c in STATE_COLUMNS[2:])]])
    kstate = np.zeros((1, 3))
    out = [np.zeros((1, n)) for _ in range(3)] + [np.zeros((1, n), dtype=np.int64)]
    _advance_rows(_substep_table(params, 1, M), np.full((1, n), u), np.zeros((1, n)),
                  np.zeros((1, 1)), False, -1, 1, n, M, DT, True, True, True, np.full(1, 1e-3),
                  np.zeros(1), *out, 0, 1, sfx, kstate)  # fmt: skip
    accel = 2e-5 * u / DT  # the centre of mass's [rad/s^2]
    settled = (1.0 + cols["payload_ratio"]) * kstate[0, 1]
    batched = make_batched("resonance", {"coupling": 1.0, **mode}, DT)
    assert batched.fusion_gain() * accel == pytest.approx(settled, rel=1e-3)
