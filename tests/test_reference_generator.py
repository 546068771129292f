"""The reference generator: reproducible draws in range, qualifying runs, truth in the
project's names, no code shared with the project's models, and the CLI."""

from __future__ import annotations

import ast
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import isp_twin.reference as reference
from isp_twin.cli import main
from isp_twin.identification.measured import load_measured
from isp_twin.model.effects import EFFECTS
from isp_twin.model.parameters import REGIMES, RateParams
from isp_twin.reference import EFFECT_NAMES, RUN_NAMES, design_experiment, draw_axis
from isp_twin.reference.experiment import MAX_ANGLE_DEG, MIN_FOOTPRINT_SIGMA, MIN_MOVING

ALLOWED = {"numpy", "scipy", "numba", "isp_twin.errors", "isp_twin.reference"}


def test_the_package_imports_only_stdlib_numpy_scipy_numba_and_errors():
    package = Path(reference.__file__).parent
    modules = sorted(package.glob("*.py"))
    assert len(modules) >= 6
    for path in modules:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{path.name}: relative import"
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
                names = names[:1] if node.module != "isp_twin" else names[1:]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                ok = top in sys.stdlib_module_names or any(
                    name == a or name.startswith(a + ".") for a in ALLOWED
                )
                assert ok, f"{path.name} imports {name}"


def test_truth_uses_the_project_names_of_every_effect_and_of_the_rate_form():
    assert reference.REGIME_NAMES == REGIMES
    assert set(EFFECT_NAMES) == set(EFFECTS)
    for name in EFFECT_NAMES:
        drawn = draw_axis(0, name)
        (effect,) = drawn.effects
        assert effect.name == name
        assert tuple(effect.truth(drawn.axis.inertia_kg_m2)) == EFFECTS[name].param_names
    rate = reference.rate_form(draw_axis(0).axis)
    fields = set(RateParams.__dataclass_fields__)
    assert all(set(v) - {"zoh_factor"} == fields for v in rate.values())


def test_draws_are_reproducible_and_share_the_base_axis_across_effects():
    assert draw_axis(7, "cogging") == draw_axis(7, "cogging")
    assert draw_axis(7, "cogging").axis == draw_axis(7).axis == draw_axis(7, "resonance").axis
    assert draw_axis(7).axis != draw_axis(8).axis


def test_draws_stay_in_the_documented_ranges():
    for seed in range(200):
        d = draw_axis(seed)
        a = d.axis
        assert 0.005 <= a.time_constant_s <= 1.0
        assert 0.01 <= d.sensors.gyro_noise_rad_s / (math.pi / 180) <= 0.1
        assert 14 <= d.sensors.resolver_bits <= 19
        for r in a.regimes:
            assert 1.0 <= r.static_nm / r.coulomb_nm <= 2.5 + 1e-12
            assert 0.05 - 1e-12 <= r.coulomb_nm / d.peak_drive_nm
            assert r.static_nm / d.peak_drive_nm <= 0.6 + 1e-12
    # alpha spans two decades over the draws (times the rate scale)
    alphas = [draw_axis(s).axis.regimes[0].alpha_s_rad for s in range(200)]
    assert max(alphas) / min(alphas) > 100.0


@pytest.mark.parametrize("seed, effect", [(5, None), (1, "deadzone")])
def test_experiments_are_reproducible_and_visit_every_regime(seed, effect):
    one = design_experiment(seed, effect)
    two = design_experiment(seed, effect)
    assert one.truth() == two.truth()
    for name in RUN_NAMES:
        run = one.runs[name]
        np.testing.assert_array_equal(run.omega, two.runs[name].omega)
        assert run.u.shape == (6000,)
        assert np.all(run.moving_per_regime() >= MIN_MOVING)
        assert np.max(np.abs(run.angle)) < math.radians(MAX_ANGLE_DEG)
        # moving samples really move and resting samples rest
        assert np.all((run.rate != 0.0) == (run.regime >= 0))
    kinds = [one.excitations[n].kind for n in RUN_NAMES]
    assert kinds[:2] == ["cosine", "cosine"] and kinds[2] in ("multisine", "steps")
    if effect is not None:
        assert one.footprint_sigma >= MIN_FOOTPRINT_SIGMA
    # the measured reading is the clean one plus noise of the stated sigma
    noise = np.concatenate([one.runs[n].omega - one.runs[n].omega_clean for n in RUN_NAMES])
    assert noise.std() == pytest.approx(one.drawn.sensors.gyro_noise_rad_s, rel=0.05)


def test_cli_writes_the_three_runs_and_the_truth(tmp_path, capsys):
    out = tmp_path / "ref"
    assert (
        main(["generate", "--reference", "--seed", "4", "--effect", "unbalance", "--out", str(out)])
        == 0
    )
    runs = [load_measured(out / f"{name}.csv") for name in RUN_NAMES]
    assert all(len(r) == 6000 and r.dt == pytest.approx(1e-3) for r in runs)
    truth = yaml.safe_load((out / "truth.yaml").read_text())
    assert truth["effect"] == "unbalance" and truth["seed"] == 4
    assert set(truth["effects"][0]["params"]) == set(EFFECTS["unbalance"].param_names)
    assert set(truth["rate_form"]["regimes"]) == set(REGIMES)
    # the files agree with the truth: start angle (within a resolver count), sample count
    lsb = truth["sensors"]["resolver_lsb_deg"]
    for name, run in zip(RUN_NAMES, runs):
        start = truth["runs"][name]["initial_angle_deg"]
        assert abs(math.degrees(run.angle[0]) - start) <= 0.5 * lsb + 1e-9
        assert truth["runs"][name]["n_samples"] == len(run)


def test_cli_names_an_unknown_effect_in_one_line(tmp_path, capsys):
    out = tmp_path / "ref"
    assert main(["generate", "--reference", "--effect", "coging", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "coging" in err and "cogging" in err
    assert not out.exists()


@pytest.mark.parametrize("seed", range(6))
def test_the_truth_rate_form_drives_the_project_model_onto_the_reference(seed):
    """The mapping is exact while sliding with a point-sampled gyro: the project's Eq. 6
    model with the truth's rate form must follow the reference (the angle given, as
    identification does); a mapping error in units, sign or regime order would not."""
    from isp_twin.model.axis_model import simulate as eq6
    from isp_twin.reference import Excitation, Sensors, rate_form, simulate

    drawn = draw_axis(seed)
    rate = rate_form(drawn.axis)
    fields = ("pole", "gain", "static", "coulomb", "alpha")
    params = RateParams(*(np.array([rate[r][f] for r in REGIMES]) for f in fields))
    u = Excitation("cosine", 900.0, 0.5, n_samples=4000).command()
    ref = simulate(drawn.axis, u, (), Sensors(gyro_averaged=False), theta0_rad=-0.05, seed=None)
    model = eq6(params, u, 1e-3, angle0=-0.05, angle_measured=ref.angle)
    error = np.sqrt(np.mean((model.omega - ref.rate) ** 2))
    # Only stops and breakaways inside a sample differ: far below 1 % of the motion.
    assert error < 0.01 * np.sqrt(np.mean(ref.rate**2))


def test_effect_without_reference_is_refused_in_one_line(tmp_path, capsys):
    assert main(["generate", "--effect", "cogging", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--reference" in err
