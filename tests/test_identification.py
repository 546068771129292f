"""Identification: recovery of known parameters, interval coverage, regimes not
visited, reproducibility, and the `identify` command end to end."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from isp_twin.cli import main
from isp_twin.errors import DataError
from isp_twin.identification.cost import rmse
from isp_twin.identification.equation_error import equation_error_estimate
from isp_twin.identification.experiments import PAPER_SET, generate_set
from isp_twin.identification.fit import (
    DE_STALL_GAIN,
    DE_STALL_GENERATIONS,
    IdentificationStatus,
    Settings,
    identify,
    stalled,
    to_axis_params,
)
from isp_twin.identification.measured import save_measured
from isp_twin.identification.side_angle import fused_angle
from isp_twin.model.parameters import (
    RATE_LAYOUT,
    AxisParams,
    ParameterSet,
    RegimeParams,
    load_parameters,
    save_parameters,
)
from isp_twin.model.substep_model import EQ6
from isp_twin.units import DEG

# Short test data: two of the paper-set variations at 1 Hz, 1000 samples
# (one period each); together they visit all four regimes (>= 85 samples).
SHORT = tuple(
    dataclasses.replace(PAPER_SET[i], freq_hz=1.0, n_samples=1000, name=f"short{i}") for i in (0, 3)
)
# The data are made by Eq. 6 itself (`axis_model`): fitted with Eq. 6 (m = 1).
FAST = Settings(generations=0, refine_evaluations=200, integration=EQ6)


def _data(params, noise, seed=0, excitations=SHORT):
    lsb = 360 / 2**16 if noise else 0.0
    return generate_set(
        params, "inner_az", excitations, gyro_noise_deg_s=noise, resolver_lsb_deg=lsb, seed=seed
    )


def _perturbed_prior(axis):
    """A wrong prior (start and fallback values): every number off by 20-40 %."""
    regs = [
        dataclasses.replace(
            r,
            a=1 - (1 - r.a) * 1.3,
            Ke=r.Ke * 0.7,
            Ts=r.Ts * 1.4,
            Tc=r.Tc * 0.75,
            alpha=r.alpha * 1.3,
        )
        for r in axis.regimes
    ]
    return dataclasses.replace(axis, regimes=tuple(regs))


@pytest.fixture(scope="module")
def truth(paper_params):
    return paper_params.axis("inner_az")


@pytest.fixture(scope="module")
def clean_result(paper_params, truth):
    return identify(_data(paper_params, 0.0), _perturbed_prior(truth), FAST)


@pytest.fixture(scope="module")
def noisy_results(paper_params, truth):
    return [identify(_data(paper_params, 0.02, seed), truth, FAST) for seed in (0, 10, 20)]


def test_noise_free_data_recovers_every_identifiable_quantity_within_1_percent(clean_result, truth):
    x_true = truth.rate_params().to_vector()
    assert clean_result.identifiable.all()
    rel = np.abs(clean_result.vector / x_true - 1)
    assert rel.max() < 0.01
    assert clean_result.cost < 1e-3 * DEG


def test_paper_form_keeps_b_and_recovers_ke_ts_tc(clean_result, truth):
    prior = _perturbed_prior(truth)
    axis = to_axis_params(clean_result, prior)
    for got, true, pri in zip(axis.regimes, truth.regimes, prior.regimes):
        assert got.b == pri.b == true.b
        for f in ("a", "Ke", "Ts", "Tc", "alpha"):
            assert getattr(got, f) == pytest.approx(getattr(true, f), rel=0.01)
        assert all(math.isnan(ci.b) for ci in axis.ci95)


def test_noisy_data_intervals_cover_the_truth(noisy_results, truth):
    x_true = truth.rate_params().to_vector()
    inside = []
    for res in noisy_results:
        ok = res.identifiable
        inside.extend((np.abs(res.vector - x_true) <= res.ci95)[ok])
        # The fit reaches the gyro noise (0.02 deg/s), not more.
        assert res.cost / DEG == pytest.approx(0.02, rel=0.1)
    assert len(inside) >= 50
    assert np.mean(inside) >= 0.9


def test_result_is_exactly_what_the_parameter_file_stores(clean_result, truth, tmp_path):
    prior = _perturbed_prior(truth)
    axis = to_axis_params(clean_result, prior)
    path = save_parameters(ParameterSet("t", {"inner_az": axis}), tmp_path / "p.yaml")
    back = load_parameters(path).axis("inner_az").rate_params().to_vector()
    np.testing.assert_allclose(back, clean_result.vector, rtol=1e-12)


def test_equation_error_start_is_close_on_clean_data(paper_params, truth):
    est = equation_error_estimate(_data(paper_params, 0.0), _perturbed_prior(truth).rate_params())
    # Poles and gains are nearly exact in one step; the curve levels are looser.
    x, t = (RATE_LAYOUT.as_table(p.to_vector()) for p in (est, truth.rate_params()))
    pole_gain = [RATE_LAYOUT.field_index("pole"), RATE_LAYOUT.field_index("gain")]
    assert np.abs(x[:, pole_gain] / t[:, pole_gain] - 1).max() < 0.05


def test_fused_angle_is_exact_without_sensor_errors(paper_params):
    d = _data(paper_params, 0.0)[0]
    np.testing.assert_allclose(fused_angle(d), d.angle, atol=1e-12)


def test_regime_never_visited_keeps_its_prior_and_gets_no_interval(paper_params, truth):
    # PAPER_SET[1] stays at positive angles: only R+ and R- are visited.
    exc = (dataclasses.replace(PAPER_SET[1], n_samples=1000, name="right_only"),)
    data = _data(paper_params, 0.02, 0, exc)
    prior = _perturbed_prior(truth)
    res = identify(data, prior, FAST)
    assert res.regime_identified == (True, True, False, False)
    assert res.visits[2] == res.visits[3] == 0
    left = slice(RATE_LAYOUT.regime_slice("L+").start, None)  # regimes L+ and L-
    assert not res.identifiable[left].any()
    assert np.isnan(res.ci95[left]).all()
    np.testing.assert_array_equal(res.vector[left], prior.rate_params().to_vector()[left])
    axis = to_axis_params(res, prior)
    assert axis.identified == (True, True, False, False)
    assert axis.regimes[2:] == prior.regimes[2:]
    assert axis.ci95[2] is None and axis.ci95[3] is None


def test_same_seed_same_result_and_the_search_improves_the_start(paper_params, truth):
    data = _data(paper_params, 0.02, excitations=SHORT[:1])
    s = Settings(seed=7, generations=3, population=8, refine=False, integration=EQ6)
    a = identify(data, _perturbed_prior(truth), s)
    b = identify(data, _perturbed_prior(truth), s)
    np.testing.assert_array_equal(a.vector, b.vector)
    assert a.history == b.history
    assert a.cost <= a.initial_cost
    assert list(a.history) == sorted(a.history, reverse=True)


def test_the_search_log_is_the_history_with_stage_and_evaluations(noisy_results):
    for res in noisy_results:
        assert [step.best_cost for step in res.log] == list(res.history)
        assert res.log[0].stage == "start" and res.log[0].best_cost == res.initial_cost
        assert {step.stage for step in res.log[1:]} <= {"refine", "timing", "search"}
        counts = [step.evaluations for step in res.log]
        assert counts == sorted(counts) and 0 < counts[-1] <= res.evaluations
        # The enum and the cost agree: at the noise exactly when within the ratio.
        at_noise = res.cost <= res.settings.converged_ratio * res.noise
        assert (res.outcome is IdentificationStatus.AT_NOISE) == at_noise


@pytest.mark.parametrize(
    "change, outcome",
    [
        ({"refine": False}, IdentificationStatus.NOT_AT_NOISE),
        ({"refine_evaluations": 3}, IdentificationStatus.MAX_EVALUATIONS),
        ({"refine_evaluations": 2000}, IdentificationStatus.CONVERGED),
        ({"refine": False, "generations": 2, "population": 5}, IdentificationStatus.NOT_AT_NOISE),
    ],
)
def test_the_outcome_says_why_a_fit_above_the_noise_ended(paper_params, truth, change, outcome):
    # Half the noise floor: no fit reaches it (white noise leaves an RMS
    # error of sigma * sqrt(1 - 20/N) at the truth, N ~ 1000 samples), so
    # every run ends "above the noise" and the enum says why.
    data = _data(paper_params, 0.02, excitations=SHORT[:1])
    s = dataclasses.replace(FAST, converged_ratio=0.5, **change)
    res = identify(data, _perturbed_prior(truth), s)
    assert res.cost > s.converged_ratio * res.noise
    assert res.outcome is outcome
    assert ("search" in {step.stage for step in res.log}) == (s.generations > 0)


def test_stalled_counts_the_gain_over_the_last_generations():
    n, gain = DE_STALL_GENERATIONS, DE_STALL_GAIN
    flat = [1.0] * (n + 1)
    assert stalled(flat) and not stalled(flat[:-1])
    # Twice the gain per window, for three windows: never stalled.
    steady = [(1 - 2 * gain / n) ** k for k in range(3 * n)]
    assert not any(stalled(steady[:k]) for k in range(1, len(steady) + 1))
    # Half of it: stalled once a window has passed.
    slow = [(1 - 0.5 * gain / n) ** k for k in range(n + 1)]
    assert stalled(slow)


def test_the_evolution_stops_at_its_first_stall(paper_params, truth):
    # Half the noise floor forces the global search (as above); it starts
    # from the least squares' end, which its population does not beat.
    data = _data(paper_params, 0.02, excitations=SHORT[:1])
    s = dataclasses.replace(FAST, converged_ratio=0.5, generations=20, population=8)
    res = identify(data, _perturbed_prior(truth), s)
    first = next(k for k, step in enumerate(res.log) if step.stage == "search")
    costs = [res.log[first - 1].best_cost]
    costs += [step.best_cost for step in res.log if step.stage == "search"]
    assert len(costs) - 1 < s.generations
    assert stalled(costs) and not any(stalled(costs[:k]) for k in range(1, len(costs)))
    assert f"({len(costs) - 1} of {s.generations} generations, stalled)" in res.status


def test_no_visited_regime_is_an_error(paper_params, truth):
    data = _data(paper_params, 0.0)
    with pytest.raises(DataError, match="no regime has 10000 moving samples"):
        identify(data, truth, dataclasses.replace(FAST, min_regime_samples=10_000))


def test_identify_command_end_to_end(tmp_path, paper_params, truth, capsys):
    data = _data(paper_params, 0.02)
    paths = [str(save_measured(d, tmp_path / f"{d.name}.csv")) for d in data]
    out, js = tmp_path / "id.yaml", tmp_path / "id.json"
    argv = [
        "identify",
        paths[0],
        paths[1],
        "--validate",
        paths[1],
        "--out",
        str(out),
        "--json",
        str(js),
        "--generations",
        "1",
        "--population",
        "6",
        "--refine-evaluations",
        "60",
        "--substeps",
        "1",
        "--quiet",
    ]
    assert main(argv) == 0
    assert capsys.readouterr().err == ""  # --quiet and not a terminal: no progress
    ps = load_parameters(out)  # directly usable by `isp-twin run`
    assert ps.axis("inner_az").identified == (True,) * 4
    assert ps.axis("outer_az") == paper_params.axis("outer_az")
    summary = json.loads(js.read_text())
    assert set(summary) >= {"parameters", "ci95", "identifiable", "rmse_train", "rmse_validation"}
    assert summary["outcome"] in {s.value for s in IdentificationStatus}
    assert summary["search_log"][0]["stage"] == "start"
    assert 0 < summary["search_log"][-1]["evaluations"] <= summary["evaluations"]
    assert summary["identifiable"]["R+"]["b"] is False and summary["ci95"]["R+"]["b"] is None
    assert list(summary["rmse_validation"]) == [data[1].name]
    assert summary["rmse_validation"][data[1].name] == pytest.approx(0.02, rel=0.2)
    report = (tmp_path / "id_report.md").read_text()
    assert "Table 2" in report and "Table 3" in report
    assert (tmp_path / f"id_report_{data[0].name}.png").stat().st_size > 1000
    # The file as stored (6 digits) reproduces the reported fit, and fits the
    # data as well as the truth does.
    got = ps.axis("inner_az").rate_params()
    assert rmse(got, data, integration=EQ6) / DEG == pytest.approx(summary["cost_deg_s"], rel=1e-6)
    assert rmse(got, data, integration=EQ6) <= 1.05 * rmse(
        truth.rate_params(), data, integration=EQ6
    )
    # ...and the identified twin runs the closed-loop scenarios.
    scenario = tmp_path / "short.yaml"
    scenario.write_text(
        "kind: closed_loop\nduration_s: 3.0\n"
        "turntable:\n  table_yaw: {amplitude_deg: 1.0, freq_hz: 0.5}\n"
    )
    metrics = tmp_path / "m.json"
    run = ["run", str(scenario), "--params", str(out), "--no-recording", "--json", str(metrics)]
    assert main(run) == 0
    assert json.loads(metrics.read_text())["parameters_file"] == str(out)


def test_identify_command_bad_data_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text(
        "t,u,omega\n" + "".join(f"{k * 1e-3},1,{'nan' if k == 30 else 0}\n" for k in range(50))
    )
    out = tmp_path / "never.yaml"
    assert main(["identify", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.csv: row 32" in err
    assert not out.exists()


def test_identify_command_rejects_data_at_another_sample_rate(tmp_path, capsys):
    t = np.arange(100) * 2e-3
    path = tmp_path / "slow.csv"
    np.savetxt(
        path,
        np.column_stack([t, 100 * np.sin(t), np.sin(t), np.cos(t)]),
        delimiter=",",
        header="t,u,omega,theta",
        comments="",
    )
    assert main(["identify", str(path), "--out", str(tmp_path / "p.yaml")]) == 2
    assert (
        "slow.csv: measured sample period 0.002 s is +100 % off the 0.001 s"
        in capsys.readouterr().err
    )


def test_real_free_spinning_motor_with_the_side_fixed(tmp_path):
    """The HSM150 excerpt (tests/data/README.md): torque in, spinning one way.

    With the side fixed to R only R+ is visited; the other three regimes keep
    the prior and are flagged, and the fit beats the prior.
    """
    from isp_twin.identification.measured import load_measured, mapping_from_options

    real = Path(__file__).parent / "data" / "hsm150_idf_pos_0.06_1_excerpt.mat"
    d = load_measured(
        real,
        mapping_from_options(["t=data:0", "u=data:4", "omega=data:3*rad/s", "theta=data:2*rad"]),
    )
    base = RegimeParams(
        a=1 - 7.03e-5 * 1e-3 / 1.2e-4, b=1e-3 / 1.2e-4 / DEG, Ke=1.0, Ts=0.025, Tc=0.02, alpha=0.01
    )
    prior = AxisParams(regimes=(base,) * 4)
    res = identify([d], prior, Settings(side_source="right", generations=0, refine_evaluations=30))
    assert res.regime_identified == (True, False, False, False)
    assert res.cost < rmse(prior.rate_params(), [d], "right")
    assert res.identifiable[5:].sum() == 0


def test_identify_command_reads_mat_through_a_data_description(tmp_path):
    real = Path(__file__).parent / "data" / "hsm150_idf_pos_0.06_1_excerpt.mat"
    desc = tmp_path / "hsm150.yaml"
    desc.write_text(
        "variable: data\n"
        "columns:\n"
        "  t: 0\n"
        "  u: 4\n"
        "  omega: {column: 3, unit: rad/s}\n"
        "  theta: {column: 2, unit: rad}\n"
    )
    out, js = tmp_path / "p.yaml", tmp_path / "p.json"
    argv = [
        "identify",
        str(real),
        "--describe",
        str(desc),
        "--side",
        "right",
        "--out",
        str(out),
        "--json",
        str(js),
        "--generations",
        "0",
        "--refine-evaluations",
        "5",
        "--no-report",
        "--quiet",
    ]
    assert main(argv) == 0
    summary = json.loads(js.read_text())
    assert summary["regime_identified"] == {"R+": True, "R-": False, "L+": False, "L-": False}
    assert load_parameters(out).axis("inner_az").identified == (True, False, False, False)


def _with_effect(data, truth, spec):
    """The runs re-simulated (noise-free) with Eq. 6 plus one extra effect."""
    from isp_twin.model.axis_model import simulate
    from isp_twin.model.effects import make_effect

    out = []
    for d in data:
        res = simulate(
            truth.rate_params(),
            d.u,
            d.dt,
            angle0=float(d.angle[0]),
            effects=[make_effect(spec, d.dt)],
        )
        out.append(dataclasses.replace(d, omega=res.omega, angle=res.angle))
    return out


def test_identification_keeps_the_prior_effects_in_the_fit_and_the_file(
    paper_params, truth, tmp_path
):
    from isp_twin.model.parameters import EffectSpec

    # A centring cable spring: 300 rad/s^2 per rad is a pull of 15.7 rad/s^2
    # at 3 deg, of the order of the friction levels (b*Ts/T ~ 10-40 rad/s^2).
    spring = EffectSpec("cable_spring", {"stiffness_1_s2": 300.0, "offset_rad_s2": 0.0})
    data = _with_effect(_data(paper_params, 0.0), truth, spring)
    declared = dataclasses.replace(_perturbed_prior(truth), effects=(spring,))
    result = identify(data, declared, FAST)
    x_true = truth.rate_params().to_vector()
    assert result.effects == (spring,)
    assert np.abs(result.vector / x_true - 1).max() < 0.01
    out = tmp_path / "with_spring.yaml"
    save_parameters(paper_params.with_axis("inner_az", to_axis_params(result, declared)), out)
    assert load_parameters(out).axis("inner_az").effects == (spring,)
    # The report's numbers come from the model with the spring as well.
    from isp_twin.identification.report import result_json

    summary = result_json(result, "inner_az", to_axis_params(result, declared), data[:1])
    assert summary["effects_held"] == [{"name": "cable_spring", "parameters": spring.params}]
    assert max(summary["rmse_validation"].values()) < 1e-9
    # Without the spring declared, Eq. 6 alone cannot explain the same data.
    blind = identify(data, _perturbed_prior(truth), FAST)
    assert blind.effects == ()
    assert blind.cost > 10 * result.cost
    assert np.abs(blind.vector / x_true - 1).max() > 0.01
