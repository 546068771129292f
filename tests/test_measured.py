"""Loading measured open-loop data: formats, mappings, derived signals, bad data."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from isp_twin.errors import DataError, ResourceNotFound
from isp_twin.identification.measured import (
    MIN_SAMPLES,
    DataMapping,
    MeasuredData,
    differentiate_angle,
    integrate_rate,
    load_data_description,
    load_measured,
    mapping_from_options,
    save_measured,
)
from isp_twin.units import DEG

N = 200
DT = 1e-3


def _signals():
    t = np.arange(N) * DT
    u = 500 * np.cos(2 * np.pi * 2 * t)
    omega_deg_s = 10 * np.sin(2 * np.pi * 2 * t)
    theta_deg = 1.0 + np.cumsum(omega_deg_s) * DT
    return t, u, omega_deg_s, theta_deg


def _write_csv(path, header, columns, fmt="%.12g"):
    np.savetxt(
        path, np.column_stack(columns), delimiter=",", header=",".join(header), comments="", fmt=fmt
    )
    return path


@pytest.fixture
def canonical(tmp_path):
    t, u, w, y = _signals()
    return _write_csv(tmp_path / "run.csv", ["t", "u", "omega", "theta"], [t, u, w, y])


def test_canonical_csv_is_converted_to_si(canonical):
    t, u, w, y = _signals()
    d = load_measured(canonical)
    assert d.name == "run" and len(d) == N
    assert d.dt == pytest.approx(DT)
    np.testing.assert_allclose(d.omega, w * DEG, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(d.angle, y * DEG, rtol=1e-10)
    np.testing.assert_allclose(d.u, u)


def test_save_then_load_round_trips(tmp_path):
    t, u, w, y = _signals()
    d = MeasuredData("x", t, u, w * DEG, y * DEG, None, DT)
    back = load_measured(save_measured(d, tmp_path / "x.csv"))
    for a, b in ((d.t, back.t), (d.u, back.u), (d.omega, back.omega), (d.angle, back.angle)):
        np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-15)


def test_columns_may_come_in_any_order(tmp_path):
    t, u, w, y = _signals()
    path = _write_csv(tmp_path / "r.csv", ["theta", "omega", "u", "t"], [y, w, u, t])
    np.testing.assert_allclose(load_measured(path).omega, w * DEG, rtol=1e-10, atol=1e-14)


def test_angle_only_data_gets_a_lag_free_derivative(tmp_path):
    t, u, _, _ = _signals()
    f = 2.0
    w = 10 * np.sin(2 * np.pi * f * t)  # deg/s, the exact derivative of y
    y = 1.0 + 10 / (2 * np.pi * f) * (1 - np.cos(2 * np.pi * f * t))
    path = _write_csv(tmp_path / "a.csv", ["t", "u", "theta"], [t, u, y])
    d = load_measured(path)
    inner = slice(10, -10)
    err = d.omega[inner] / DEG - w[inner]
    assert np.abs(err).max() < 1e-3 * np.abs(w).max()
    # A lag tau would leave err = -tau * dw/dt: its least-squares tau is ~0.
    dw = 10 * 2 * np.pi * f * np.cos(2 * np.pi * f * t[inner])
    tau = -np.dot(err, dw) / np.dot(dw, dw)
    # (a backward difference would give tau = DT/2)
    assert abs(tau) < 0.05 * DT


def test_derivative_of_a_quadratic_is_exact():
    t = np.arange(50) * DT
    angle = 3.0 + 2.0 * t + 5.0 * t**2
    np.testing.assert_allclose(differentiate_angle(angle, DT), 2.0 + 10.0 * t, rtol=1e-9, atol=1e-9)


def test_derivative_noise_gain_matches_the_documented_formula():
    rng = np.random.default_rng(1)
    s = 1e-3
    noise = rng.normal(0, s, 200_000)
    rate = differentiate_angle(noise, DT)[100:-100]
    w = 11
    expected = s / DT * math.sqrt(12 / (w * (w * w - 1)))
    assert np.std(rate) == pytest.approx(expected, rel=0.03)


def test_rate_only_data_integrates_the_angle(tmp_path):
    t, u, w, y = _signals()
    path = _write_csv(tmp_path / "w.csv", ["t", "u", "omega"], [t, u, w])
    d = load_measured(path)
    np.testing.assert_allclose(d.angle, integrate_rate(w * DEG, DT, 0.0), rtol=1e-9, atol=1e-15)
    assert d.angle[0] == 0.0
    shifted = load_measured(path, DataMapping(initial_angle_deg=2.0))
    np.testing.assert_allclose(shifted.angle - d.angle, 2.0 * DEG, rtol=1e-12)
    # The model's rule: y[k] - y[k-1] = dt * omega[k].
    np.testing.assert_allclose(np.diff(d.angle), DT * d.omega[1:], rtol=1e-9, atol=1e-15)


def test_mat_file_through_a_column_mapping(tmp_path):
    t, u, w, y = _signals()
    data = np.column_stack([t, np.zeros(N), y * DEG, w * DEG, u])
    path = tmp_path / "bench.mat"
    savemat(path, {"data": data, "J": 1.2e-4})
    m = mapping_from_options(["t=data:0", "u=data:4", "omega=data:3*rad/s", "theta=data:2*rad"])
    d = load_measured(path, m)
    np.testing.assert_allclose(d.omega, w * DEG, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(d.angle, y * DEG, rtol=1e-10)


def test_yaml_description_with_units_and_scale(tmp_path):
    t, u, w, y = _signals()
    path = _write_csv(
        tmp_path / "other.csv", ["time_ms", "cmd", "gyro_rad_s"], [t * 1000, u / 2, w * DEG]
    )
    desc = tmp_path / "desc.yaml"
    desc.write_text(
        "columns:\n"
        "  t: {column: time_ms, unit: ms}\n"
        "  u: {column: cmd, scale: 2}\n"
        "  omega: {column: gyro_rad_s, unit: rad/s}\n"
        "initial_angle_deg: 1.0\n"
    )
    d = load_measured(path, load_data_description(desc))
    assert d.dt == pytest.approx(DT)
    np.testing.assert_allclose(d.u, u, rtol=1e-10)
    np.testing.assert_allclose(d.omega, w * DEG, rtol=1e-9, atol=1e-14)
    assert d.angle[0] == pytest.approx(1.0 * DEG)


# ---------------------------------------------------------------- bad data


def test_missing_file_is_named(tmp_path):
    with pytest.raises(ResourceNotFound, match="nope.csv"):
        load_measured(tmp_path / "nope.csv")


def test_nan_names_file_row_and_column(tmp_path):
    t, u, w, y = _signals()
    w = w.copy()
    w[41] = np.nan
    path = _write_csv(tmp_path / "nan.csv", ["t", "u", "omega", "theta"], [t, u, w, y])
    # Data row 41 is file line 43 (line 1 is the header).
    with pytest.raises(DataError, match=r"nan\.csv: row 43, column 'omega'.*NaN or inf"):
        load_measured(path)


def test_inf_in_mat_names_the_index(tmp_path):
    t, u, w, y = _signals()
    data = np.column_stack([t, u, w])
    data[7, 1] = np.inf
    path = tmp_path / "inf.mat"
    savemat(path, {"data": data})
    m = mapping_from_options(["t=data:0", "u=data:1", "omega=data:2"])
    with pytest.raises(DataError, match=r"inf\.mat: index 7, data\[:, 1\] \(u\)"):
        load_measured(path, m)


def test_time_going_backwards_is_located(tmp_path):
    t, u, w, y = _signals()
    t = t.copy()
    t[100] = t[98]
    path = _write_csv(tmp_path / "back.csv", ["t", "u", "omega", "theta"], [t, u, w, y])
    with pytest.raises(DataError, match=r"row 102.*not strictly increasing"):
        load_measured(path)


def test_non_uniform_time_says_by_how_much(tmp_path):
    t, u, w, y = _signals()
    t = t.copy()
    t[150:] += 0.0005  # one step of 1.5 ms among 1 ms steps: 50 % off
    path = _write_csv(tmp_path / "jit.csv", ["t", "u", "omega", "theta"], [t, u, w, y])
    with pytest.raises(DataError, match=r"row 152.*not uniform.*50 % off"):
        load_measured(path)


def test_missing_column_lists_what_exists(tmp_path):
    t, u, w, y = _signals()
    path = _write_csv(tmp_path / "m.csv", ["t", "cmd", "omega"], [t, u, w])
    with pytest.raises(DataError, match=r"m\.csv: missing column 'u'.*has t, cmd, omega"):
        load_measured(path)


def test_neither_rate_nor_angle_is_an_error(tmp_path):
    t, u, w, y = _signals()
    path = _write_csv(tmp_path / "m.csv", ["t", "u"], [t, u])
    with pytest.raises(DataError, match="omega.*theta"):
        load_measured(path)


def test_too_few_samples(tmp_path):
    t, u, w, y = (x[: MIN_SAMPLES - 1] for x in _signals())
    path = _write_csv(tmp_path / "short.csv", ["t", "u", "omega", "theta"], [t, u, w, y])
    with pytest.raises(DataError, match=rf"short\.csv: too few samples: {MIN_SAMPLES - 1}"):
        load_measured(path)


def test_text_in_a_number_field_is_located(tmp_path, canonical):
    lines = canonical.read_text().splitlines()
    lines[5] = lines[5].replace(lines[5].split(",")[2], "abc", 1)
    path = tmp_path / "txt.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"row 6, column 'omega': not a number"):
        load_measured(path)


def test_mapping_to_a_missing_csv_column(tmp_path, canonical):
    m = mapping_from_options(["t=t", "u=u", "omega=gyro"])
    with pytest.raises(DataError, match=r"omega -> column 'gyro' does not exist"):
        load_measured(canonical, m)


def test_mapping_to_a_missing_mat_column_or_variable(tmp_path):
    t, u, w, y = _signals()
    path = tmp_path / "b.mat"
    savemat(path, {"data": np.column_stack([t, u, w])})
    m = mapping_from_options(["t=data:0", "u=data:1", "omega=data:5"])
    with pytest.raises(
        DataError, match=r"column 5 of 'data' does not exist \('data' has 3 columns"
    ):
        load_measured(path, m)
    m = mapping_from_options(["t=dta:0", "u=dta:1", "omega=dta:2"])
    with pytest.raises(DataError, match=r"variable 'dta' does not exist \(did you mean 'data'\?\)"):
        load_measured(path, m)


def test_mat_without_mapping_says_how(tmp_path):
    path = tmp_path / "b.mat"
    savemat(path, {"data": np.zeros((30, 3))})
    with pytest.raises(DataError, match="needs a mapping"):
        load_measured(path)


@pytest.mark.parametrize(
    "option, message",
    [
        ("omega", "expected KEY=SOURCE"),
        ("speed=data:3", "unknown signal 'speed'"),
        ("omega=data:x", "column index 'x' is not an integer"),
        ("omega=data:3*furlongs", "neither a number nor a unit of omega"),
    ],
)
def test_bad_map_options(option, message):
    with pytest.raises(DataError, match=message):
        mapping_from_options([option])


def test_bad_data_description_names_the_key(tmp_path):
    desc = tmp_path / "d.yaml"
    desc.write_text("columns:\n  t: 0\n  omega: {colum: 3}\n")
    with pytest.raises(DataError, match=r"d\.yaml: columns\.omega\.colum: unknown key"):
        load_data_description(desc)


REAL = (
    Path(__file__).parent / "data" / "hsm150_idf_pos_0.06_1_excerpt.mat"
)  # see tests/data/README.md


def test_real_hsm150_excerpt_loads_in_si():
    m = mapping_from_options(["t=data:0", "u=data:4", "omega=data:3*rad/s", "theta=data:2*rad"])
    d = load_measured(REAL, m)
    assert len(d) == 600 and d.dt == pytest.approx(1e-3)
    assert set(np.round(d.u, 6)) == {0.05, 0.06}  # README: torque step 0.05 -> 0.06 N·m at 10 s
    assert d.t[np.argmax(d.u > 0.055)] == pytest.approx(10.0, abs=1.5e-3)
    assert 100 < d.omega.min() and d.omega.max() < 250  # rad/s, as the README says (~200 rad/s)
    assert (np.diff(d.angle) >= 0).all()  # free spinning, angle only grows
    # The rate column agrees with the position column's derivative (both SI).
    np.testing.assert_allclose(
        differentiate_angle(d.angle, d.dt)[50:-50].mean(), d.omega[50:-50].mean(), rtol=0.01
    )
