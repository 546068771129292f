"""The reference simulator against closed forms that owe nothing to the project's model code."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from isp_twin.errors import ParameterError
from isp_twin.reference import REGIME_NAMES, Axis, RegimeFriction, Sensors, draw_axis, simulate
from isp_twin.reference import effects as fx
from isp_twin.reference.excitation import Excitation

POINT = Sensors(gyro_averaged=False)
AVERAGED = Sensors(gyro_averaged=True)


def linear_axis(inertia=0.01, viscous=0.2, gain=1e-4) -> Axis:
    """No friction at all: J dw/dt = Km u - eta w."""
    return Axis(inertia, viscous, gain, (RegimeFriction(0.0, 0.0, 0.0),) * 4)


def test_linear_axis_step_response_is_the_first_order_closed_form():
    axis = linear_axis()
    tau, w_inf = 0.01 / 0.2, 1e-4 * 500.0 / 0.2
    u = np.full(300, 500.0)
    t = np.arange(300) * 1e-3
    rate = w_inf * (1.0 - np.exp(-t / tau))
    angle = 0.1 + w_inf * (t - tau * (1.0 - np.exp(-t / tau)))
    point = simulate(axis, u, sensors=POINT, theta0_rad=0.1, seed=None)
    np.testing.assert_allclose(point.omega, rate, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(point.angle, angle, rtol=1e-9, atol=1e-12)
    averaged = simulate(axis, u, sensors=AVERAGED, theta0_rad=0.1, seed=None)
    np.testing.assert_allclose(averaged.omega[1:], np.diff(angle) / 1e-3, rtol=1e-9)


def four_regime_axis() -> Axis:
    # Breakaway levels 20 % apart, gains and viscosities differing per regime,
    # so using another regime's values would flip a stick/slip verdict below.
    return Axis(
        0.01,
        0.2,
        1e-4,
        (
            RegimeFriction(0.030, 0.020, 5.0, 1.0, 1.0),
            RegimeFriction(0.036, 0.024, 3.0, 1.1, 0.9),
            RegimeFriction(0.043, 0.028, 8.0, 0.9, 1.2),
            RegimeFriction(0.052, 0.035, 2.0, 1.2, 0.8),
        ),
    )


@pytest.mark.parametrize("regime", range(4))
def test_stick_below_breakaway_and_motion_above_in_every_regime(regime):
    axis = four_regime_axis()
    r = axis.regimes[regime]
    direction = 1.0 if REGIME_NAMES[regime].endswith("+") else -1.0
    theta0 = 0.1 if REGIME_NAMES[regime].startswith("R") else -0.1
    breakaway_u = r.static_nm / (axis.motor_gain_nm_per_digit * r.gain_scale)
    below = simulate(
        axis, np.full(500, 0.97 * direction * breakaway_u), theta0_rad=theta0, seed=None
    )
    assert np.all(below.rate == 0.0) and np.all(below.angle == theta0)
    above_u = 1.03 * direction * breakaway_u
    above = simulate(axis, np.full(3000, above_u), theta0_rad=theta0, seed=None)
    assert np.all(above.regime[1:] == regime)
    # Steady sliding: Km u = eta w + Tc + (Ts - Tc) exp(-alpha |w|), solved independently.
    km, eta = axis.motor_gain_nm_per_digit * r.gain_scale, axis.viscous_nm_s * r.viscous_scale

    def balance(w):
        return (
            km * abs(above_u)
            - eta * w
            - r.coulomb_nm
            - (r.static_nm - r.coulomb_nm) * math.exp(-r.alpha_s_rad * w)
        )

    steady = brentq(balance, 1e-9, km * abs(above_u) / eta)
    assert above.rate[-1] == pytest.approx(direction * steady, rel=1e-6)


def test_cable_spring_dissipates_energy_and_stops_inside_the_stick_band():
    axis = four_regime_axis()
    spring = fx.CableSpring(stiffness_nm_rad=0.5, centre_rad=0.02)
    run = simulate(axis, np.zeros(4000), (spring,), POINT, theta0_rad=-0.3, seed=None)
    energy = 0.5 * axis.inertia_kg_m2 * run.rate**2 + 0.5 * 0.5 * (run.angle - 0.02) ** 2
    assert np.all(np.diff(energy) <= 1e-12)
    assert run.rate[-1] == 0.0
    # At rest the spring torque cannot exceed the breakaway torque of the side it rests on.
    side = 0 if run.angle[-1] > 0 else 2
    pull = -0.5 * (run.angle[-1] - 0.02)
    assert abs(pull) <= axis.regimes[side + (pull < 0)].static_nm


def test_cable_spring_static_equilibrium_without_friction():
    spring = fx.CableSpring(stiffness_nm_rad=2.0, centre_rad=-0.05)
    run = simulate(linear_axis(), np.full(3000, 400.0), (spring,), POINT, seed=None)
    assert run.angle[-1] == pytest.approx(-0.05 + 1e-4 * 400.0 / 2.0, rel=1e-6)


@pytest.mark.parametrize(
    "effect, static_map",
    [
        (
            fx.Deadzone(width_digits=150.0),
            lambda u: np.sign(u) * np.maximum(np.abs(u) - 150.0, 0.0),
        ),
        (fx.Saturation(limit_digits=420.0), lambda u: np.clip(u, -420.0, 420.0)),
    ],
)
def test_amplifier_static_maps(effect, static_map):
    axis = linear_axis()
    for u in (-900.0, -300.0, -100.0, 0.0, 120.0, 400.0, 700.0):
        run = simulate(axis, np.full(800, u), (effect,), POINT, seed=None)  # 16 time constants
        expected = 1e-4 * static_map(np.array(u)) / 0.2
        assert run.rate[-1] == pytest.approx(expected, rel=1e-6, abs=1e-12)


def test_a_pure_delay_shifts_the_response_by_exactly_its_samples():
    axis = draw_axis(5).axis  # with friction: the shift must hold for any plant
    u = Excitation("steps", 900.0, 5.0, n_samples=2000, seed=3).command()
    u[:10] = 0.0
    plain = simulate(axis, u, sensors=POINT, seed=None)
    for samples in (1, 4, 7):
        delayed = simulate(axis, u, (fx.InputDelay(samples * 1e-3),), POINT, seed=None)
        np.testing.assert_array_equal(delayed.omega[samples:], plain.omega[:-samples])
    # A fractional delay: the step arrives half-way between the two whole ones.
    step = np.r_[np.zeros(5), np.full(45, 500.0)]
    lo, mid, hi = (
        simulate(linear_axis(), step, (fx.InputDelay(d),), POINT, seed=None)
        for d in (2e-3, 2.5e-3, 3e-3)
    )
    moving = lo.rate > 0
    assert np.all(mid.rate[moving] < lo.rate[moving])
    assert np.all(mid.rate[moving] >= hi.rate[moving]) and np.any(mid.rate > hi.rate)


def test_a_delay_off_the_integration_grid_is_refused():
    with pytest.raises(ParameterError, match="whole number"):
        simulate(linear_axis(), np.zeros(10), (fx.InputDelay(1.23e-4),), seed=None)


def test_two_mass_resonance_frequency_from_the_spectrum():
    mode = fx.PayloadMode(
        payload_fraction=0.2,
        stiffness_nm_rad=0.002 * (2 * math.pi * 40) ** 2,
        damping_nm_s_rad=1e-4,
    )
    axis = linear_axis(inertia=0.01, viscous=1e-4)
    u = np.zeros(8000)
    u[:3] = 800.0  # a short pulse rings the free mode
    run = simulate(axis, u, (mode,), POINT, seed=None)
    w = run.omega - run.omega.mean()
    spectrum = np.abs(np.fft.rfft(w * np.hanning(w.size)))
    freqs = np.fft.rfftfreq(w.size, 1e-3)
    band = freqs > 5.0
    peak = freqs[band][np.argmax(spectrum[band])]
    expected = mode.free_freq_hz(0.01)  # sqrt(k (1/J1 + 1/J2)) / 2 pi
    assert abs(peak - expected) <= freqs[1]
    assert expected == pytest.approx(
        math.sqrt(0.002 * (2 * math.pi * 40) ** 2 * (1 / 0.008 + 1 / 0.002)) / (2 * math.pi)
    )


def test_a_frictionless_two_mass_axis_converges_to_its_exact_solution_at_second_order():
    # Without friction the two-mass axis is linear: motor side
    # J1 w1' = Km u - eta w1 + k x + c x', payload deflection
    # x'' = -(k/J2) x - (c/J2) x' - w1', gyro on the payload w1 + x'. Its
    # exact zero-order-hold solution (matrix exponential) is what the
    # averaged gyro reads in the limit; the step's predictor-corrector is
    # second order, so halving the step quarters the error. A mis-signed
    # payload state in the corrector made it first order (benchmark
    # resonance seed 0: 0.04 % of the rate at 10 sub-steps, ~1 noise sigma).
    from scipy.linalg import expm

    j, f, k, c, eta, km = 0.01, 0.2, 0.002 * (2 * math.pi * 60) ** 2, 2e-3, 0.2, 1e-4
    j1, j2 = (1 - f) * j, f * j
    mode = fx.PayloadMode(payload_fraction=f, stiffness_nm_rad=k, damping_nm_s_rad=c)
    axis = linear_axis(inertia=j, viscous=eta, gain=km)
    u = np.where(np.arange(400) < 150, 600.0, 300.0)
    # State (theta1, w1, x, x'), input u; the payload angle theta1 + x.
    a = np.array(
        [
            [0, 1, 0, 0],
            [0, -eta / j1, k / j1, c / j1],
            [0, 0, 0, 1],
            [0, eta / j1, -k / j1 - k / j2, -c / j1 - c / j2],
        ]
    )
    b = np.array([0, km / j1, 0, -km / j1])
    aug = np.zeros((5, 5))
    aug[:4, :4], aug[:4, 4] = a * 1e-3, b * 1e-3
    step = expm(aug)
    state = np.array([0.1, 0, 0, 0])
    payload = [0.1]
    for uk in u[:-1]:
        state = step[:4, :4] @ state + step[:4, 4] * uk
        payload.append(state[0] + state[2])
    exact = np.diff(payload) / 1e-3
    errors = [
        np.max(np.abs(simulate(axis, u, (mode,), AVERAGED, substeps=m, theta0_rad=0.1,
                               seed=None).omega_clean[1:] - exact))
        for m in (10, 20, 40)
    ]  # fmt: skip
    assert errors[0] / errors[1] > 3.5 and errors[1] / errors[2] > 3.5, errors


@pytest.mark.parametrize(
    "seed, effect, share",
    [(s, e, 0.1) for s in (2, 3) for e in (None, "lugre", "cogging", "unbalance")]
    # The payload once needed 0.5: its corrector's mis-signed state (see the
    # exact-solution test above), not the breakaway, made it first order.
    + [(4, "resonance", 0.1)],
)
def test_halving_the_integration_step_changes_the_response_by_far_less_than_the_noise(
    seed, effect, share
):
    drawn = draw_axis(seed, effect)
    u = Excitation("cosine", 900.0, 0.7, n_samples=3000).command()
    runs = [
        simulate(drawn.axis, u, drawn.effects, drawn.sensors, substeps=s, seed=None)
        for s in (10, 20)
    ]
    change = np.sqrt(np.mean((runs[0].omega_clean - runs[1].omega_clean) ** 2))
    assert change < share * drawn.sensors.gyro_noise_rad_s


def test_a_non_finite_command_is_refused_naming_the_sample():
    u = np.zeros(20)
    u[7] = np.nan
    with pytest.raises(ParameterError, match="sample 7"):
        simulate(linear_axis(), u, seed=None)


def test_a_runaway_stops_at_the_sample_where_the_rate_passes_the_limit():
    """A frictionless axis driven to 5000 rad/s passes the 1000 rad/s runaway
    limit at t = -tau ln(1 - 1000/5000) = 11.2 ms (tau = 50 ms): the end of
    sample 11, the first whose end state is checked past it."""
    from isp_twin.errors import SimulationDiverged

    axis = linear_axis(gain=1.0)  # w_inf = 1.0 * 1000 / 0.2 = 5000 rad/s
    with pytest.raises(SimulationDiverged, match=r"at sample 11 \(rate 1\.0\de\+03 rad/s\)"):
        simulate(axis, np.full(100, 1000.0), seed=None)


def test_an_effect_the_simulator_does_not_know_is_refused():
    with pytest.raises(ParameterError, match="unknown effect"):
        simulate(linear_axis(), np.zeros(10), effects=(object(),), seed=None)


def test_the_compiled_angle_torques_are_the_effects_own_bit_for_bit():
    """The integrator evaluates the angle torques from a parameter table
    (`axis._angle_torque`); each must be its class's ``torque_nm`` exactly,
    alone and summed in the order given."""
    from isp_twin.reference.axis import _angle_torque, _torque_table

    torques = (
        fx.Cogging(amplitude_nm=0.013, period_rad=2 * math.pi / 37, phase_rad=0.7),
        fx.CableSpring(stiffness_nm_rad=0.21, centre_rad=-0.05),
        fx.Unbalance(amplitude_nm=0.04, phase_rad=-1.1),
        fx.TorqueOffset(torque_offset_nm=-0.008),
    )
    angles = np.random.default_rng(3).uniform(-0.6, 0.6, 200)
    for chosen in [(t,) for t in torques] + [torques]:
        codes, table = _torque_table(chosen)
        for theta in angles:
            expected = 0.0
            for t in chosen:
                expected += t.torque_nm(float(theta))
            assert _angle_torque(codes, table, float(theta)) == expected
