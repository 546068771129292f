"""The effect library: each effect's physics, the null parameters, the batched
form against the scalar one, and the effects hook of the fast axis model."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.errors import ParameterError
from isp_twin.model.axis_model import simulate
from isp_twin.model.effects import EFFECTS, Effect, effect_class, make_effect
from isp_twin.model.effects.batched import make_batched
from isp_twin.model.parameters import EffectSpec, load_parameters
from isp_twin.resources import default_parameters_path

DT = 1e-3
LIBRARY = (
    "cogging",
    "cable_spring",
    "unbalance",
    "torque_offset",
    "input_delay",
    "deadzone",
    "saturation",
    "sensor_bias",
    "lugre",
    "resonance",
)
EXAMPLE = {
    "cogging": {"amplitude_rad_s2": 3.0, "period_rad": 0.1, "phase_rad": 0.4},
    "cable_spring": {"stiffness_1_s2": 20.0, "offset_rad_s2": 2.0},
    "unbalance": {"amplitude_rad_s2": 6.0, "phase_rad": -0.7},
    "torque_offset": {"accel_rad_s2": 4.0},
    "input_delay": {"delay_s": 0.0035},
    "deadzone": {"width_digits": 200.0},
    "saturation": {"limit_digits": 1500.0},
    "sensor_bias": {"bias_rad_s": 0.01, "scale": 0.03},
    "lugre": {"accel_rad_s2": 12.0, "presliding_rad": 0.003},
    "resonance": {
        "freq_hz": 40.0,
        "damping_ratio": 0.05,
        "coupling": 0.15,
        "payload_fraction": 0.1,
    },
}


def run_hooks(effect: Effect, u, angle, rate):
    """Step every hook of an effect along a trajectory, as the engines do."""
    effect.reset()
    out = [
        (effect.command(a), effect.acceleration(b, c), effect.measure(c))
        for a, b, c in zip(u, angle, rate)
    ]
    return np.array(out, dtype=float)


def trajectory(n=400, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.uniform(-3000, 3000, n)
    rate = np.cumsum(rng.normal(0, 0.02, n))
    rate[100:130] = 0.0  # a stick phase
    angle = np.cumsum(rate) * DT
    return u, angle, rate


def test_the_library_is_registered_with_bounds_and_null_parameters():
    for name in LIBRARY:
        cls = EFFECTS[name]
        assert set(cls.bounds) == set(cls.param_names) == set(cls.null) == set(EXAMPLE[name])


@pytest.mark.parametrize("name", LIBRARY)
def test_null_parameters_change_nothing(name):
    u, angle, rate = trajectory()
    out = run_hooks(make_effect(EffectSpec(name, EFFECTS[name].null), DT), u, angle, rate)
    np.testing.assert_allclose(out[:, 0], u, atol=1e-12)
    np.testing.assert_allclose(out[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(out[:, 2], rate, atol=1e-12)


@pytest.mark.parametrize("name", LIBRARY)
def test_batched_form_equals_one_scalar_effect_per_set(name):
    u, angle, rate = trajectory(seed=1)
    rng = np.random.default_rng(2)
    sets = [{k: v * rng.uniform(0.5, 1.5) for k, v in EXAMPLE[name].items()} for _ in range(3)]
    batched = make_batched(name, {k: np.array([s[k] for s in sets]) for k in EXAMPLE[name]}, DT)
    got = run_hooks_batched(batched, u, angle, rate, 3)
    for i, s in enumerate(sets):
        want = run_hooks(make_effect(EffectSpec(name, s), DT), u, angle, rate)
        np.testing.assert_allclose(got[:, :, i], want, rtol=1e-12, atol=1e-12)


def run_hooks_batched(effect, u, angle, rate, p):
    effect.reset()
    out = []
    for a, b, c in zip(u, angle, rate):
        ones = np.ones(p)
        out.append(
            [
                np.broadcast_to(effect.command(a), (p,)),
                np.broadcast_to(effect.acceleration(b * ones, c * ones), (p,)),
                np.broadcast_to(effect.measure(c * ones), (p,)),
            ]
        )
    return np.array(out)


@pytest.mark.parametrize("name", LIBRARY)
def test_whole_run_hooks_equal_the_hooks_sample_after_sample(name):
    """`command_run`/`measure_run` and, for a torque of the angle alone, one
    elementwise call over (N, rows) give what the sample loop gives, row by
    row with per-row parameters (fractional delays included)."""
    rng = np.random.default_rng(3)
    p = 3
    sets = [{k: v * rng.uniform(0.5, 1.5) for k, v in EXAMPLE[name].items()} for _ in range(p)]
    batched = make_batched(name, {k: np.array([s[k] for s in sets]) for k in EXAMPLE[name]}, DT)
    runs = [trajectory(n=300, seed=10 + i) for i in range(p)]
    u, angle, rate = (np.array([r[j] for r in runs]) for j in range(3))
    batched.reset()
    want_u = np.array([batched.command(u[:, k]) for k in range(u.shape[1])]).T
    batched.reset()
    want_m = np.array([batched.measure(rate[:, k]) for k in range(u.shape[1])]).T
    batched.reset()
    np.testing.assert_array_equal(batched.command_run(u), want_u)
    batched.reset()
    np.testing.assert_array_equal(batched.measure_run(rate), want_m)
    if not batched.acceleration_uses_rate:
        want_a = np.array([batched.acceleration(angle[:, k], None) for k in range(u.shape[1])])
        np.testing.assert_allclose(batched.acceleration(angle.T, None), want_a, rtol=1e-14, atol=0)


def test_unknown_or_missing_effect_parameters_are_named():
    with pytest.raises(ParameterError, match="period_rad"):
        make_effect(EffectSpec("cogging", {"amplitude_rad_s2": 1.0, "phase_rad": 0.0}), DT)
    with pytest.raises(ParameterError, match="did you mean 'cogging'"):
        make_effect(EffectSpec("coging", {}), DT)
    with pytest.raises(ParameterError, match="missing parameter"):
        make_batched("deadzone", {}, DT)


def test_every_lookup_names_an_unknown_effect_and_lists_the_known_ones():
    known = ", ".join(sorted(EFFECTS))
    for lookup in (
        lambda: effect_class("coging"),
        lambda: make_effect(EffectSpec("coging", {}), DT),
        lambda: make_batched("coging", {}, DT),
    ):
        with pytest.raises(ParameterError) as caught:
            lookup()
        message = str(caught.value)
        assert "'coging'" in message and "did you mean 'cogging'" in message
        assert message.endswith(f"known: {known}") and "\n" not in message


@pytest.mark.parametrize(
    "params",
    [
        {"amplitude_rad_s2": 1.0, "phase_rad": 0.0},  # period_rad missing
        {**EXAMPLE["cogging"], "period": 0.1},  # an unknown one
    ],
)
def test_one_parameter_check_serves_the_scalar_and_the_batched_effect(params):
    messages = []
    for build in (
        lambda: make_effect(EffectSpec("cogging", params), DT),
        lambda: make_batched("cogging", params, DT),
    ):
        with pytest.raises(ParameterError) as caught:
            build()
        messages.append(str(caught.value))
    assert messages[0] == messages[1]


def test_diagnosis_tests_the_registered_effects_in_report_order():
    from isp_twin.diagnosis.prepared_runs import LIBRARY as CANDIDATES

    assert CANDIDATES == LIBRARY == tuple(EFFECTS)


def test_cogging_is_periodic_in_angle_with_the_given_period():
    e = make_effect(EffectSpec("cogging", EXAMPLE["cogging"]), DT)
    y = np.linspace(-1, 1, 101)
    np.testing.assert_allclose(e.acceleration(y + 0.1, 0.0), e.acceleration(y, 0.0), atol=1e-9)
    assert np.max(np.abs(e.acceleration(y, 0.0))) == pytest.approx(3.0, rel=0.01)


def test_cable_spring_is_linear_in_angle():
    e = make_effect(EffectSpec("cable_spring", EXAMPLE["cable_spring"]), DT)
    assert e.acceleration(0.0, 0.3) == pytest.approx(2.0)
    assert e.acceleration(0.1, 0.0) - e.acceleration(0.0, 0.0) == pytest.approx(-2.0)


def test_unbalance_is_a_sine_of_angle():
    e = make_effect(EffectSpec("unbalance", EXAMPLE["unbalance"]), DT)
    assert e.acceleration(np.pi / 2 + 0.7, 0.0) == pytest.approx(6.0)
    assert e.acceleration(0.7, 0.0) == pytest.approx(0.0, abs=1e-12)


def test_input_delay_shifts_by_whole_samples_and_interpolates_fractions():
    u = np.arange(20.0) ** 2
    whole = run_hooks(
        make_effect(EffectSpec("input_delay", {"delay_s": 0.003}), DT), u, u * 0, u * 0
    )[:, 0]
    np.testing.assert_allclose(whole[3:], u[:-3])
    np.testing.assert_allclose(whole[:3], u[0])  # the command before the start is the first one
    half = run_hooks(
        make_effect(EffectSpec("input_delay", {"delay_s": 0.0025}), DT), u, u * 0, u * 0
    )[:, 0]
    np.testing.assert_allclose(half[3:], 0.5 * (u[:-3] + u[1:-2]))


def test_deadzone_and_saturation_shape_the_command():
    dz = make_effect(EffectSpec("deadzone", {"width_digits": 200.0}), DT)
    sat = make_effect(EffectSpec("saturation", {"limit_digits": 1500.0}), DT)
    u = np.array([-2000.0, -150.0, 0.0, 199.0, 500.0, 1600.0])
    np.testing.assert_allclose(dz.command(u), [-1800.0, 0.0, 0.0, 0.0, 300.0, 1400.0])
    np.testing.assert_allclose(sat.command(u), [-1500.0, -150.0, 0.0, 199.0, 500.0, 1500.0])


def test_sensor_bias_and_scale():
    e = make_effect(EffectSpec("sensor_bias", EXAMPLE["sensor_bias"]), DT)
    assert e.measure(0.0) == pytest.approx(0.01)
    assert e.measure(1.0) == pytest.approx(1.04)


def test_lugre_bristles_act_as_coulomb_in_steady_sliding_and_turn_round_over_the_presliding_distance():
    e = make_effect(EffectSpec("lugre", EXAMPLE["lugre"]), DT)
    for _ in range(2000):  # 0.2 rad of sliding at +0.1 rad/s
        acc = e.acceleration(0.0, 0.1)
    assert acc == pytest.approx(-12.0, rel=1e-6)
    # Reverse at -0.1 rad/s: the bristle force flips sign once the axis has
    # travelled a few pre-sliding distances (z relaxes as exp(-x/z_max)).
    forces = np.array([e.acceleration(0.0, -0.1) for _ in range(400)])
    # Still bent the old way: the first sample's force is the mean of the
    # relaxing z over it, -12 (2 (1 - exp(-s)) / s - 1) with s = 0.1 T / z_max.
    s = 0.1 * DT / 0.003
    assert forces[0] == pytest.approx(-12.0 * (2.0 * (1.0 - np.exp(-s)) / s - 1.0), rel=1e-9)
    travel_at_zero = (np.argmax(forces > 0) + 1) * 0.1 * DT
    assert travel_at_zero == pytest.approx(0.003 * np.log(2), rel=0.1)
    assert forces[-1] == pytest.approx(12.0, rel=1e-3)
    assert e.acceleration(0.0, 0.0) == 0.0  # at rest the bristles belong to stiction


def test_lugre_force_is_the_mean_of_the_bristle_force_over_the_sample():
    """The force held over a sample is the exact mean of ``-accel z(t)/z_max``
    for the rate held, also where the bristles turn round within the sample
    (travel per sample > z_max): checked against the state equation
    ``dz/dt = v - |v| z / z_max`` integrated by fine Euler steps."""
    accel, zmax = 12.0, 3e-4
    e = make_effect(EffectSpec("lugre", {"accel_rad_s2": accel, "presliding_rad": zmax}), DT)
    z = 0.0
    for rate in (0.05, 0.05, -1.0, -0.2, 0.4, 0.01):  # travel/z_max per sample 0.03 to 3.3
        fine = 20000
        h = DT / fine
        forces = np.empty(fine)
        for i in range(fine):  # midpoint rule on the fine grid
            z_mid = z + 0.5 * h * (rate - abs(rate) * z / zmax)
            forces[i] = -accel * z_mid / zmax
            z += h * (rate - abs(rate) * z_mid / zmax)
        assert e.acceleration(0.0, rate) == pytest.approx(forces.mean(), rel=1e-6, abs=1e-9)


def test_resonance_rings_at_its_damped_frequency_and_decays_at_its_damping():
    p = EXAMPLE["resonance"]
    e = make_effect(EffectSpec("resonance", p), DT)
    rate = np.r_[0.0, np.ones(1999)]  # a rate step = an acceleration impulse
    ring = np.array([e.measure(r) for r in rate]) - rate
    wn = 2 * np.pi * p["freq_hz"]
    wd = wn * np.sqrt(1 - p["damping_ratio"] ** 2)
    crossings = np.flatnonzero(np.diff(np.sign(ring[1:])) != 0)
    period = 2 * np.mean(np.diff(crossings)) * DT
    assert period == pytest.approx(2 * np.pi / wd, rel=0.01)
    peaks = [np.max(np.abs(ring[1 + i * 100 : 1 + (i + 1) * 100])) for i in (0, 5)]
    assert peaks[1] / peaks[0] == pytest.approx(np.exp(-p["damping_ratio"] * wn * 0.5), rel=0.1)
    assert abs(ring[1]) == pytest.approx(p["coupling"], rel=0.1)  # gyro sees -coupling*step at once


@pytest.fixture(scope="module")
def rate():
    return load_parameters(default_parameters_path()).axis("inner_az").rate_params()


def test_simulate_without_effects_is_unchanged_by_the_effects_argument(rate):
    u = trajectory(800)[0]
    a = simulate(rate, u, DT)
    b = simulate(rate, u, DT, effects=())
    np.testing.assert_array_equal(a.omega, b.omega)
    assert b.omega_true is None


def test_a_torque_effect_enters_the_fast_model_as_the_twins_euler_step(rate):
    # A constant acceleration c over one sample adds c*T of rate (the twin's
    # explicit-Euler step): the same as extra_rate of that size.
    u = np.full(600, 1500.0)  # moves in + on the right side throughout
    c = 5.0
    via_effect = simulate(
        rate,
        u,
        DT,
        angle0=0.1,
        effects=[make_effect(EffectSpec("torque_offset", {"accel_rad_s2": c}), DT)],
    )
    via_extra = simulate(rate, u, DT, angle0=0.1, extra_rate=np.full(600, c * DT))
    np.testing.assert_allclose(via_effect.omega, via_extra.omega, rtol=1e-12, atol=1e-15)


def test_measurement_effects_change_the_reported_rate_not_the_motion(rate):
    u = trajectory(800)[0]
    plain = simulate(rate, u, DT)
    biased = simulate(
        rate, u, DT, effects=[make_effect(EffectSpec("sensor_bias", EXAMPLE["sensor_bias"]), DT)]
    )
    np.testing.assert_array_equal(biased.omega_true, plain.omega)
    np.testing.assert_allclose(biased.omega, 0.01 + 1.03 * plain.omega)


def test_command_effects_match_a_pre_shaped_command(rate):
    u = trajectory(800)[0]
    shaped = simulate(rate, np.clip(u, -1500, 1500), DT)
    sat = simulate(
        rate, u, DT, effects=[make_effect(EffectSpec("saturation", {"limit_digits": 1500.0}), DT)]
    )
    np.testing.assert_array_equal(sat.omega, shaped.omega)


@pytest.mark.parametrize(
    "freq, zeta, coupling", [(40.0, 0.05, 0.15), (3.0, 0.5, -1.0), (300.0, 0.002, 0.3)]
)
def test_resonance_discretization_equals_the_matrix_exponential(freq, zeta, coupling):
    from scipy.linalg import expm

    from isp_twin.model.effects.resonance import _discretize

    wn = 2 * np.pi * freq
    aug = np.zeros((3, 3))
    aug[0, 1], aug[1, 0], aug[1, 1], aug[1, 2] = 1.0, -wn * wn, -2 * zeta * wn, -coupling
    want = expm(aug * DT)
    phi, gamma = _discretize(freq, zeta, coupling, DT)
    np.testing.assert_allclose(phi, want[:2, :2], atol=1e-12)
    np.testing.assert_allclose(gamma, want[:2, 2], atol=1e-15)


def test_every_effect_module_is_listed_in_the_registry():
    import importlib
    import inspect
    import pkgutil

    import isp_twin.model.effects

    found = {}
    for info in pkgutil.iter_modules(isp_twin.model.effects.__path__):
        module = importlib.import_module(f"isp_twin.model.effects.{info.name}")
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, Effect) and cls is not Effect and cls.__module__ == module.__name__:
                found[cls.name] = cls
    assert found == EFFECTS
    assert all(name == cls.__module__.rsplit(".", 1)[1] for name, cls in EFFECTS.items())
