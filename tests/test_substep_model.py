"""The sub-stepped Eq. 6 (`isp_twin.model.substep_model`): Eq. 6 at m = 1, exact
zero-order hold at any m, convergence in m, and the true parameters of
reference-simulator axes at the noise."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.identification.read_out import gyro_reading
from isp_twin.model.axis_model import simulate
from isp_twin.model.effects import Effect, make_effect
from isp_twin.model.parameters import EffectSpec, RateParams
from isp_twin.model.substep_model import EQ6, Integration, simulate_substeps
from isp_twin.vocabulary import SIDE_L, SIDE_R

DT = 1e-3
N = 3000


def _params(n_sets: int, seed: int = 0, alpha: float | None = None) -> RateParams:
    """Random rate-form sets around a 20 ms axis with strong friction, (P, 4) each."""
    rng = np.random.default_rng(seed)
    pole = np.exp(-DT / rng.uniform(0.005, 0.05, (n_sets, 4)))
    gain = rng.uniform(2e-5, 6e-5, (n_sets, 4)) * (1 - pole) / 0.05
    coulomb = gain * 1000 * rng.uniform(0.1, 0.5, (n_sets, 4))
    static = coulomb * rng.uniform(1.0, 2.5, (n_sets, 4))
    al = rng.uniform(0.5, 20.0, (n_sets, 4)) if alpha is None else np.full((n_sets, 4), alpha)
    return RateParams(pole=pole, gain=gain, static=static, coulomb=coulomb, alpha=al)


def _command(seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(N) * DT
    u = 900 * np.cos(2 * np.pi * 1.3 * t) - 150 + 40 * rng.standard_normal(N)
    angle = np.deg2rad(3 * np.sin(2 * np.pi * 0.9 * t) + 0.5)
    return u, angle


@pytest.mark.parametrize("teacher", [True, False])
def test_eq6_form_is_axis_model_bit_for_bit_without_the_stribeck_exponential(teacher):
    # alpha = 0: exp(-0) = 1 in numpy and in libm, so nothing but the
    # integration scheme could differ.
    params = _params(6, alpha=0.0)
    u, angle = _command()
    kw = {"angle_measured": angle} if teacher else {}
    a = simulate(params, u, DT, **kw)
    b = simulate_substeps(params, u, DT, integration=EQ6, **kw)
    assert np.array_equal(a.omega, b.omega)
    assert np.array_equal(a.angle, b.angle)
    assert np.array_equal(a.regime, b.regime)
    assert np.count_nonzero(a.omega == 0.0) > 50  # sticks and reversals were exercised
    averaged = simulate_substeps(params, u, DT, integration=EQ6, gyro_average=True, **kw)
    assert np.array_equal(averaged.omega, gyro_reading(a.omega, True))


def test_eq6_form_matches_axis_model_with_stribeck_and_effects():
    # numpy's vectorized exp and the C library's differ in the last bit on
    # a few per cent of arguments: equal to rounding, same stick decisions.
    params = _params(5, seed=3)
    u, angle = _command(2)
    specs = [
        EffectSpec("cable_spring", {"stiffness_1_s2": 40.0, "offset_rad_s2": 1.0}),
        EffectSpec("input_delay", {"delay_s": 0.0025}),
        EffectSpec("sensor_bias", {"bias_rad_s": 0.001, "scale": 0.02}),
    ]
    a = simulate(params, u, DT, angle_measured=angle, effects=[make_effect(e, DT) for e in specs])
    b = simulate_substeps(
        params, u, DT, angle_measured=angle, effects=[make_effect(e, DT) for e in specs],
        integration=EQ6,
    )  # fmt: skip
    assert np.array_equal(a.regime, b.regime)
    assert np.abs(a.omega - b.omega).max() <= 1e-12 * np.abs(a.omega).max()


def test_substeps_are_the_exact_zero_order_hold_of_the_sample():
    # Constant friction (alpha = 0) while sliding one way: m sub-steps of the
    # held drive land exactly on Eq. 6's sample, for any m.
    params = _params(4, seed=5, alpha=0.0)
    u = np.full(400, 1000.0)
    eq6 = simulate_substeps(params, u, DT, omega0=0.5, angle0=0.1, integration=EQ6)
    assert np.all(eq6.omega > 0)  # never stops: a pure sliding test
    for m in (2, 7, 10):
        fine = simulate_substeps(params, u, DT, omega0=0.5, angle0=0.1, integration=Integration(m))
        np.testing.assert_allclose(fine.omega, eq6.omega, rtol=1e-10)


def test_response_converges_as_the_substeps_shrink():
    params = _params(4, seed=7)
    u, angle = _command(3)

    def run(m):
        return simulate_substeps(
            params, u, DT, angle_measured=angle, integration=Integration(m), gyro_average=True
        ).omega

    coarse, mid, fine = run(5), run(20), run(80)
    err_coarse = np.sqrt(np.mean((coarse - fine) ** 2))
    err_mid = np.sqrt(np.mean((mid - fine) ** 2))
    assert err_mid < 0.5 * err_coarse


def test_true_parameters_of_a_reference_axis_reach_the_noise_only_sub_stepped():
    """The premise of the sub-stepped model (docs/identification.md): the
    truth of a reference axis written in the Eq. 6 form is at the noise with
    m = 10, and well above it with Eq. 6 (m = 1). Seed 2003 (time constant
    0.53 s, sharp Stribeck curves) shaped no choice."""
    from isp_twin.identification.cost import rmse
    from isp_twin.identification.measured import MeasuredData
    from isp_twin.identification.read_out import Timing
    from isp_twin.reference import design_experiment

    exp = design_experiment(2003)
    truth = exp.truth()
    rf = truth["rate_form"]["regimes"]
    fields = ("pole", "gain", "static", "coulomb", "alpha")
    rate = RateParams.from_vector(
        np.array([[rf[r][f] for f in fields] for r in ("R+", "R-", "L+", "L-")]).ravel()
    )
    sigma = truth["sensors"]["gyro_noise_rad_s"]
    runs = [MeasuredData(n, r.t, r.u, r.omega, r.theta, None, DT) for n, r in exp.runs.items()]
    averaged = Timing(0.0, True)  # the reference gyro averages over the sample

    def ratio(run, integration):
        return float(rmse(rate, [run], timing=averaged, integration=integration)) / sigma

    assert max(ratio(r, Integration(10)) for r in runs) < 1.2
    assert max(ratio(r, EQ6) for r in runs) > 2.0


def test_a_fractional_input_delay_switches_the_command_inside_the_sample():
    # A frictionless axis, a step delayed 4.4 samples: the held command
    # switches 0.4 into the sample, a sub-step boundary at m = 10, so the
    # sub-stepped rate is the continuous response from that instant on
    # (the sample's mean command, Eq. 6's form, is 2 % off one sample on).
    a, g, u0 = 0.9, 1e-5, 1000.0
    zero = np.zeros((1, 4))
    params = RateParams(np.full((1, 4), a), np.full((1, 4), g), zero, zero, zero)
    u = np.where(np.arange(40) >= 10, u0, 0.0)
    delay = make_effect(EffectSpec("input_delay", {"delay_s": 4.4 * DT}), DT)
    got = simulate_substeps(params, u, DT, effects=[delay], integration=Integration(10)).omega[0]
    t = np.arange(40) - (10 + 4.4)  # samples since the switch reaches the axis
    want = np.where(t > 0, g * u0 / (1 - a) * (1 - a ** np.maximum(t, 0.0)), 0.0)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("seed", [2, 9])
def test_the_true_delay_of_a_reference_axis_reaches_the_noise_held_out(seed):
    """Reference input_delay seeds 2 (4.4 ms; it showed the problem) and 9:
    with the sample's mean command the truth stayed at 1.54 and 2.92 noise
    sigmas on the held-out steps, a breakaway one sub-sample late after
    each step (docs/diagnosis.md "Stop 29")."""
    from isp_twin.identification.cost import rmse
    from isp_twin.identification.measured import MeasuredData
    from isp_twin.identification.read_out import Timing
    from isp_twin.reference import design_experiment

    exp = design_experiment(seed, "input_delay")
    truth = exp.truth()
    rf = truth["rate_form"]["regimes"]
    fields = ("pole", "gain", "static", "coulomb", "alpha")
    rate = RateParams.from_vector(
        np.array([[rf[r][f] for f in fields] for r in truth["regime_order"]]).ravel()
    )
    r = exp.runs["heldout"]
    run = MeasuredData("heldout", r.t, r.u, r.omega, r.theta, None, DT)
    spec = EffectSpec("input_delay", truth["effects"][0]["params"])
    err = rmse(rate, [run], effects=[spec], timing=Timing(0.0, True))
    assert float(err) / truth["sensors"]["gyro_noise_rad_s"] < 1.15


@pytest.mark.parametrize("command", ["identify", "diagnose"])
def test_a_bad_substep_count_is_one_clear_error(tmp_path, capsys, command):
    from isp_twin.cli import main
    from isp_twin.identification.measured import MeasuredData, save_measured
    from isp_twin.resources import default_parameters_path

    t = np.arange(200) * DT
    run = MeasuredData("r", t, 500 * np.sin(t), 0.01 * np.sin(t), 0.001 * np.cos(t), None, DT)
    csv = save_measured(run, tmp_path / "r.csv")
    argv = [command, str(csv), "--substeps", "0", "--out", str(tmp_path / "p.yaml")]
    if command == "diagnose":
        argv += ["--params", str(default_parameters_path()), "--no-recording"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--substeps must be between 1 and 100, got 0" in err[0]
    assert not (tmp_path / "p.yaml").exists()


def test_the_kernel_calls_friction_py_compiled_bit_for_bit():
    from isp_twin.model import substep_model
    from isp_twin.model.friction_compiled import law_probe_cases, python_law

    cases = law_probe_cases()
    compiled = substep_model._law_probe(cases)
    assert set(compiled[:, 1].tolist()) == {0.0, 1.0, 2.0, 3.0}  # every regime probed
    assert np.array_equal(compiled, python_law(cases))
    assert substep_model.compiled_law_is_current()


def test_an_edit_to_friction_py_makes_the_cached_substep_kernel_stale(monkeypatch):
    from isp_twin.model import friction, substep_model

    law = friction.stribeck
    monkeypatch.setattr(friction, "stribeck", lambda *args: law(*args) * (1 + 1e-12))
    assert not substep_model.compiled_law_is_current()


def _kernel_case(m: int, side: str, n_sets: int = 7, seed: int = 11):
    """Inputs of the sub-step kernel: random sets, some rows starting at rest,
    a non-zero extra drive (as effects give), reversals and sticks."""
    from isp_twin.model.substep_model import _substep_table

    rng = np.random.default_rng(seed)
    params = _params(n_sets, seed=seed)
    u, angle = _command(seed)
    n_rows = 2 * n_sets
    table = _substep_table(
        RateParams.from_vector(np.repeat(params.to_vector(), 2, axis=0)), n_rows, m
    )
    us = np.ascontiguousarray(np.tile(u, (n_rows, 1)) * rng.uniform(0.6, 1.2, (n_rows, 1)))
    extra = 2e-3 * rng.standard_normal((n_rows, N))
    # Every third row a slow torque as strong as the command (a spring or an
    # unbalance): it opposes the command at some rests, where the rest rule
    # (`Integration.rest_drive_gain`) decides the gain.
    strong = np.arange(n_rows) % 3 == 2
    level = 0.8 * 900 * table[strong, :, 1].mean(axis=1) / table[strong, :, 5].mean(axis=1)
    extra[strong] += level[:, None] * np.sin(2 * np.pi * 0.37 * np.arange(N) * DT)
    side_y = np.ascontiguousarray(np.tile(angle, (n_rows, 1)) + rng.normal(0, 1e-3, (n_rows, 1)))
    w0 = np.where(np.arange(n_rows) % 2 == 0, 0.0, rng.normal(0, 0.05, n_rows))
    y0 = side_y[:, 0].copy()
    use_side = side == "taught"
    fixed = {"R": SIDE_R, "L": SIDE_L}.get(side, -1)
    return table, us, extra, side_y, use_side, fixed, w0, y0


def _run_kernel(kernel, case, m, mid, split, by_drive, tail=(), per_sample=False):
    table, u, extra, side_y, use_side, fixed, w0, y0 = case
    w, y = w0.copy(), y0.copy()
    out = [np.zeros(u.shape) for _ in range(3)] + [np.zeros(u.shape, dtype=np.int64)]
    spans = [(k, k + 1) for k in range(1, N)] if per_sample else [(1, N)]
    for lo, hi in spans:
        kernel(table, u, extra, side_y, use_side, fixed, lo, hi, m, DT, mid, split, by_drive, w,
               y, *out, *tail)  # fmt: skip
    return [*out, w, y]


@pytest.mark.parametrize(
    "m, mid, split, side, by_drive",
    [(10, True, True, "taught", True), (10, True, True, "own", False),
     (1, False, False, "taught", False), (3, True, False, "R", True), (7, False, True, "L", True),
     (10, True, True, "taught", False)],
)  # fmt: skip
def test_the_fast_kernel_is_the_row_by_row_loop_bit_for_bit(m, mid, split, side, by_drive):
    # The interleaved rows and the parallel blocks change only the order in
    # which independent rows are computed: every number must be the same.
    from substep_kernel_reference import advance_row_by_row

    from isp_twin.model.substep_model import _advance_blocks, _advance_rows

    case = _kernel_case(m, side)
    n_rows = case[1].shape[0]
    ref = _run_kernel(advance_row_by_row, case, m, mid, split, by_drive)
    assert np.count_nonzero(ref[0] == 0.0) > 100  # sticks were exercised
    assert len(np.unique(ref[3][:, 1:])) == (4 if side in ("taught", "own") else 2)
    # The extra drive opposes the command at some breakaways: the rest rule matters.
    other = _run_kernel(advance_row_by_row, case, m, mid, split, not by_drive)
    assert not np.array_equal(ref[0], other[0])
    args = (case, m, mid, split, by_drive)
    runs = {
        "serial": _run_kernel(_advance_rows, *args, (0, n_rows)),
        "per sample": _run_kernel(_advance_rows, *args, (0, n_rows), True),
    }
    for blocks in (1, 2, 3, n_rows):
        runs[f"{blocks} blocks"] = _run_kernel(_advance_blocks, *args, (blocks,))
    runs["2 blocks again"] = _run_kernel(_advance_blocks, *args, (2,))
    for name, got in runs.items():
        for a, b in zip(ref, got):
            assert np.array_equal(a, b), name


@pytest.mark.parametrize("parallel", [True, False])
def test_simulate_substeps_is_the_same_on_one_thread_or_all(monkeypatch, parallel):
    from isp_twin.model import substep_model

    params = _params(9, seed=13)
    u, angle = _command(4)
    before = simulate_substeps(params, u, DT, angle_measured=angle, gyro_average=True)
    monkeypatch.setattr(substep_model, "PARALLEL_MIN_SUBSTEPS", 0 if parallel else 10**12)
    after = simulate_substeps(params, u, DT, angle_measured=angle, gyro_average=True)
    for f in ("omega", "angle", "regime", "omega_true"):
        assert np.array_equal(getattr(before, f), getattr(after, f))


class _RateDrag(Effect):
    """A test-only torque of the rate: ``-per_s * rate`` [rad/s^2] (not registered)."""

    name = "rate_drag"
    param_names = ("per_s",)

    @classmethod
    def batched(cls, params):
        effect = cls.__new__(cls)
        effect.params = {"per_s": np.asarray(params["per_s"], dtype=float)}
        effect.dt = DT
        return effect

    def acceleration(self, angle, rate):
        return -self.params["per_s"] * np.asarray(rate)


def _effect_specs(rng: np.random.Generator, n_sets: int) -> dict[str, dict[str, np.ndarray]]:
    """Batched parameters (P,) of every library effect, drawn inside its bounds."""
    from isp_twin.model.effects import EFFECTS

    specs = {}
    for name, cls in EFFECTS.items():
        params = {}
        for p in cls.param_names:
            lo, hi = cls.bounds[p]
            params[p] = rng.uniform(lo, lo + 0.3 * (hi - lo), n_sets)
        specs[name] = params
    return specs


def _per_sample_loop(params, u, angle, effects, integration, omega0):
    """The effects path as it was: every hook and one kernel call per sample."""
    from isp_twin.model.substep_model import _advance_rows, _substep_table

    n_rows, n = u.shape
    m = integration.substeps
    table = _substep_table(params, n_rows, m, integration.exact_effect_hold)
    w, y = omega0.copy(), angle[:, 0].copy()
    point, reading, ang = (np.zeros((n_rows, n)) for _ in range(3))
    regime = np.zeros((n_rows, n), dtype=np.int64)
    point[:, 0] = reading[:, 0] = w
    ang[:, 0] = y
    u_eff, extra = u.copy(), np.zeros((n_rows, n))
    lead = np.zeros(n_rows)
    for e in effects:
        e.reset()
        if e.name == "input_delay":
            # The switch inside the sample goes to the kernel; the hook
            # delays by whole samples (`InputDelay.command_run_split`).
            lead, e._frac = np.broadcast_to(e._frac, (n_rows,)).copy(), 0.0 * e._frac
    for k in range(1, n):
        uk = u[:, k - 1]
        for e in effects:
            uk = e.command(uk)
        u_eff[:, k - 1] = uk
        # Integration.midstep_angle: the torque of step k at its mean angle.
        at = 0.5 * (angle[:, k - 1] + angle[:, k]) if integration.midstep_angle else angle[:, k - 1]
        extra[:, k - 1] = sum(e.acceleration(at, w) for e in effects) * DT
        _advance_rows(table, u_eff, extra, angle, True, -1, k, k + 1, m, DT,
                      *integration.kernel_flags(), w, y, point, reading, ang, regime, 0,
                      n_rows, None, None, lead)  # fmt: skip
    return point, ang, regime


@pytest.mark.parametrize(
    "names",
    [("cogging",), ("cable_spring", "unbalance", "torque_offset"), ("input_delay", "deadzone"),
     ("saturation", "cogging"), ("rate_drag", "input_delay")],
)  # fmt: skip
def test_effects_evaluated_before_the_run_give_the_per_sample_numbers(names):
    # Command hooks and angle-only accelerations are evaluated over the whole
    # run before one kernel call; the numbers are those of the per-sample loop.
    # A rate-dependent torque (`_RateDrag`; LuGre was one before its bristles
    # moved into the kernel's sub-steps) stays per sample.
    from isp_twin.model.effects.batched import make_batched

    rng = np.random.default_rng(17)
    n_sets = 5
    params = _params(n_sets, seed=19)
    u, angle = _command(5)
    specs = _effect_specs(rng, n_sets)
    angle_rows = np.tile(angle, (n_sets, 1))
    omega0 = rng.normal(0, 0.05, n_sets)

    specs["rate_drag"] = {"per_s": rng.uniform(2.0, 20.0, n_sets)}

    def effects():
        return [_RateDrag.batched(specs[n]) if n == "rate_drag" else
                make_batched(n, specs[n], DT) for n in names]  # fmt: skip

    kw = {"omega0": omega0, "angle0": angle_rows[:, 0], "angle_measured": angle_rows}
    for integration in (
        Integration(),
        Integration(midstep_angle=False),
        Integration(rest_drive_gain=False),
    ):
        got = simulate_substeps(params, u, DT, effects=effects(), integration=integration, **kw)
        want = _per_sample_loop(
            params, np.tile(u, (n_sets, 1)), angle_rows, effects(), integration, omega0
        )
        assert np.array_equal(got.omega, want[0])
        assert np.array_equal(got.angle, want[1])
        assert np.array_equal(got.regime[:, 1:], want[2][:, 1:])
    plain = simulate_substeps(params, u, DT, **kw)
    assert not np.array_equal(got.omega, plain.omega)  # the effects acted


@pytest.mark.parametrize("name", ["cogging", "cable_spring", "unbalance", "torque_offset"])
def test_an_acceleration_declared_rate_free_ignores_the_rate_and_keeps_no_state(name):
    from isp_twin.model.effects import EFFECTS
    from isp_twin.model.effects.batched import make_batched

    assert not EFFECTS[name].acceleration_uses_rate
    rng = np.random.default_rng(23)
    effect = make_batched(name, _effect_specs(rng, 6)[name], DT)
    angle = rng.uniform(-1, 1, 6)
    first = effect.acceleration(angle, rng.normal(0, 1, 6))
    for _ in range(3):
        assert np.array_equal(effect.acceleration(angle, rng.normal(0, 1, 6)), first)
        assert np.array_equal(effect.acceleration(angle, None), first)


def test_lugre_declares_that_its_acceleration_uses_the_rate():
    from isp_twin.model.effects import EFFECTS

    assert EFFECTS["lugre"].acceleration_uses_rate
