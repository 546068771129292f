"""The sub-stepped Eq. 6 (`isp_twin.substep_model`): Eq. 6 at m = 1, exact
zero-order hold at any m, convergence in m, and the true parameters of
reference-simulator axes at the noise."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.axis_model import simulate
from isp_twin.effects import make_effect
from isp_twin.identification import gyro_reading
from isp_twin.parameters import EffectSpec, RateParams
from isp_twin.substep_model import EQ6, Integration, simulate_substeps

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
    from isp_twin.identification import Timing, rmse
    from isp_twin.measured import MeasuredData
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


@pytest.mark.parametrize("command", ["identify", "diagnose"])
def test_a_bad_substep_count_is_one_clear_error(tmp_path, capsys, command):
    from isp_twin.cli import main
    from isp_twin.measured import MeasuredData, save_measured
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
    from isp_twin import substep_model
    from isp_twin.friction_compiled import law_probe_cases, python_law

    cases = law_probe_cases()
    compiled = substep_model._law_probe(cases)
    assert set(compiled[:, 1].tolist()) == {0.0, 1.0, 2.0, 3.0}  # every regime probed
    assert np.array_equal(compiled, python_law(cases))
    assert substep_model.compiled_law_is_current()


def test_an_edit_to_friction_py_makes_the_cached_substep_kernel_stale(monkeypatch):
    from isp_twin import friction, substep_model

    law = friction.stribeck
    monkeypatch.setattr(friction, "stribeck", lambda *args: law(*args) * (1 + 1e-12))
    assert not substep_model.compiled_law_is_current()
