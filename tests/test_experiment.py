"""Generated open-loop experiments: Eq. 7 input, sensor models, the paper set."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.cli import main
from isp_twin.errors import ParameterError
from isp_twin.identification.experiments import (
    EQ7,
    INNER_STOP_DEG,
    PAPER_SET,
    generate_openloop,
    generate_set,
    paper_set,
)
from isp_twin.identification.measured import load_measured
from isp_twin.identification.side_angle import regime_visits
from isp_twin.model.axis_model import simulate
from isp_twin.units import DEG


def test_eq7_command_is_the_papers_input():
    t, u = EQ7.command()
    assert t.shape == (2000,) and t[1] - t[0] == pytest.approx(1e-3)
    assert u[0] == pytest.approx(950 - 200)
    assert u[1000] == pytest.approx(950 * np.cos(np.pi) - 200)  # t = 1 s: half a period
    assert u.mean() == pytest.approx(-200, abs=1.0)


def test_noise_free_run_is_the_axis_model(paper_params):
    d = generate_openloop(
        paper_params, gyro_noise_deg_s=0, resolver_lsb_deg=0, initial_angle_deg=1.0
    )
    rate = paper_params.axis("inner_az").rate_params()
    ref = simulate(rate, d.u, 1e-3, angle0=1.0 * DEG, angle_limit=INNER_STOP_DEG * DEG)
    np.testing.assert_array_equal(d.omega, ref.omega)
    np.testing.assert_array_equal(d.angle, ref.angle)


def test_sensor_models(paper_params):
    clean = generate_openloop(paper_params, gyro_noise_deg_s=0, resolver_lsb_deg=0)
    lsb = 360 / 2**16
    noisy = generate_openloop(paper_params, gyro_noise_deg_s=0.05, resolver_lsb_deg=lsb, seed=3)
    noise = (noisy.omega - clean.omega) / DEG
    assert np.std(noise) == pytest.approx(0.05, rel=0.1)
    assert abs(np.mean(noise)) < 0.01
    steps = noisy.angle / (lsb * DEG)
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    assert np.abs(noisy.angle - clean.angle).max() <= lsb * DEG / 2 + 1e-12


def test_same_seed_same_data_other_seed_other_noise(paper_params):
    a = generate_openloop(paper_params, seed=5)
    b = generate_openloop(paper_params, seed=5)
    c = generate_openloop(paper_params, seed=6)
    np.testing.assert_array_equal(a.omega, b.omega)
    assert not np.array_equal(a.omega, c.omega)


def test_paper_set_visits_every_regime_without_reaching_a_stop(paper_params):
    for d in generate_set(paper_params, gyro_noise_deg_s=0, resolver_lsb_deg=0):
        assert np.abs(d.angle).max() < INNER_STOP_DEG * DEG
    visits = regime_visits(generate_set(paper_params, gyro_noise_deg_s=0, resolver_lsb_deg=0))
    assert (visits >= 400).all()


def test_inner_el_set_visits_every_regime_without_reaching_a_stop(paper_params):
    runs = generate_set(
        paper_params, "inner_el", paper_set("inner_el"), gyro_noise_deg_s=0, resolver_lsb_deg=0
    )
    for d in runs:
        assert np.abs(d.angle).max() < INNER_STOP_DEG * DEG
    assert (regime_visits(runs) >= 400).all()


def test_the_inner_az_set_drives_inner_el_into_a_stop(paper_params):
    # Why INNER_EL_SET exists: the elevation's mirrored half-planes drift the other way.
    runs = generate_set(paper_params, "inner_el", PAPER_SET, gyro_noise_deg_s=0, resolver_lsb_deg=0)
    assert max(np.abs(d.angle).max() for d in runs) == pytest.approx(INNER_STOP_DEG * DEG)


def test_plain_eq7_reaches_the_stop(paper_params):
    # Why PAPER_SET exists: the exact Eq. 7 run from 0 deg hits the -4 deg stop.
    d = generate_openloop(paper_params, gyro_noise_deg_s=0, resolver_lsb_deg=0)
    assert d.angle.min() == pytest.approx(-INNER_STOP_DEG * DEG)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"axis": "middle_az"}, "axis 'middle_az' unknown"),
        ({"dt": 2e-3}, "differs from the parameter set's sample_time_s"),
        ({"engine": "gpu"}, "engine 'gpu' unknown"),
        ({"gyro_noise_deg_s": -1.0}, r"gyro_noise_deg_s: -1.0 is outside \[0, inf\)"),
    ],
)
def test_bad_arguments(paper_params, kwargs, message):
    with pytest.raises(ParameterError, match=message):
        generate_openloop(paper_params, **kwargs)


def test_generate_command_writes_loadable_csv(tmp_path, capsys):
    assert main(["generate", "--out", str(tmp_path), "--quiet"]) == 0
    files = sorted(tmp_path.glob("*.csv"))
    assert [f.stem for f in files] == sorted(e.name for e in PAPER_SET)
    d = load_measured(files[0])
    assert len(d) == 2000 and d.dt == pytest.approx(1e-3)
    assert (
        main(
            [
                "generate",
                "--out",
                str(tmp_path / "one"),
                "--set",
                "eq7",
                "--samples",
                "500",
                "--quiet",
            ]
        )
        == 0
    )
    assert len(load_measured(tmp_path / "one" / "eq7.csv")) == 500


def test_the_parameter_files_effects_are_in_the_generated_data(paper_params):
    from dataclasses import replace

    from isp_twin.model.effects import make_effect
    from isp_twin.model.parameters import EffectSpec

    spring = EffectSpec("cable_spring", {"stiffness_1_s2": 300.0, "offset_rad_s2": 0.0})
    axis = replace(paper_params.axis("inner_az"), effects=(spring,))
    sprung = paper_params.with_axis("inner_az", axis)
    e = PAPER_SET[0]
    kw = dict(
        amplitude_digits=e.amplitude_digits,
        freq_hz=e.freq_hz,
        offset_digits=e.offset_digits,
        initial_angle_deg=e.initial_angle_deg,
        gyro_noise_deg_s=0.0,
        resolver_lsb_deg=0.0,
    )
    data = generate_openloop(sprung, **kw)
    t, u = e.command()
    expected = simulate(
        axis.rate_params(),
        u,
        e.dt,
        angle0=e.initial_angle_deg * DEG,
        angle_limit=INNER_STOP_DEG * DEG,
        effects=[make_effect(spring, e.dt)],
    )
    np.testing.assert_array_equal(data.omega, expected.omega)
    plain = generate_openloop(paper_params, **kw)
    assert np.abs(plain.omega - data.omega).max() > 1e-3
