"""Parameter files: Table 2 loads, round-trips, and bad files fail clearly."""

from __future__ import annotations

import numpy as np
import pytest

from isp_twin.errors import ParameterError, ResourceNotFound
from isp_twin.model.parameters import RATE_LAYOUT, REGIMES, load_parameters, save_parameters
from isp_twin.resources import default_parameters_path
from isp_twin.units import DEG

# Table 2 of the paper, in Eq. 8 order per regime: a, b, Ke, Ts, Tc, alpha.
TABLE2 = {
    "R+": (0.851, 0.491, 0.00863, 5.563, 3.176, 0.427),
    "R-": (0.889, 0.152, 0.0114, 7.117, 4.016, 0.263),
    "L+": (0.893, 0.557, 0.0119, 2.743, 1.950, 0.774),
    "L-": (0.896, 0.281, 0.0186, 4.254, 3.569, 0.166),
}


def test_table2_values_are_loaded(paper_params):
    az = paper_params.axis("inner_az")
    for name in REGIMES:
        assert az.regime(name).as_tuple() == TABLE2[name]
    assert az.ci95[REGIMES.index("R+")].Ts == 0.284
    assert paper_params.sample_time_s == 1e-3


def test_rate_form_is_the_identifiable_products(paper_params):
    rp = paper_params.axis("inner_az").rate_params()
    a, b, ke, ts, tc, alpha = np.array([TABLE2[n] for n in REGIMES]).T
    np.testing.assert_allclose(rp.gain, b * ke * DEG)
    np.testing.assert_allclose(rp.static, b * ts * DEG)
    np.testing.assert_allclose(rp.alpha * DEG, alpha)
    back = rp.to_regimes(tuple(b))
    np.testing.assert_allclose([r.Ke for r in back], ke)


def test_save_then_load_round_trips(paper_params, tmp_path):
    out = save_parameters(paper_params, tmp_path / "p.yaml")
    again = load_parameters(out)
    for axis in paper_params.axes:
        assert again.axis(axis).regimes == paper_params.axis(axis).regimes
    assert again.axis("inner_az").ci95 == paper_params.axis("inner_az").ci95


def _write_variant(tmp_path, old, new):
    text = default_parameters_path().read_text()
    assert old in text
    path = tmp_path / "bad.yaml"
    path.write_text(text.replace(old, new, 1))
    return path


def test_missing_parameter_names_file_and_key(tmp_path):
    path = _write_variant(tmp_path, "      Ts: {value: 5.563, ci95: 0.284}\n", "")
    with pytest.raises(ParameterError, match=r"bad\.yaml: axes\.inner_az\.R\+\.Ts: missing"):
        load_parameters(path)


def test_negative_parameter_is_rejected(tmp_path):
    path = _write_variant(tmp_path, "Tc: {value: 3.176", "Tc: {value: -3.176")
    with pytest.raises(ParameterError, match=r"axes\.inner_az\.R\+\.Tc: must be positive"):
        load_parameters(path)


def test_unknown_key_suggests_the_nearest(tmp_path):
    path = _write_variant(tmp_path, "alpha: {value: 0.427", "alpah: {value: 0.427")
    with pytest.raises(ParameterError, match="did you mean 'alpha'"):
        load_parameters(path)


def test_pole_outside_unit_interval_is_rejected(tmp_path):
    path = _write_variant(tmp_path, "a: {value: 0.851", "a: {value: 1.2")
    with pytest.raises(ParameterError, match=r"pole a must lie in \(0, 1\)"):
        load_parameters(path)


def test_missing_file(tmp_path):
    with pytest.raises(ResourceNotFound, match="nope.yaml"):
        load_parameters(tmp_path / "nope.yaml")


def test_the_fitted_with_block_round_trips_and_its_absence_means_none(paper_params, tmp_path):
    from dataclasses import replace

    from isp_twin.model.parameters import FittedWith

    assert all(a.fitted_with is None for a in paper_params.axes.values())
    record = FittedWith(7, True, False, True, True, 0.25)
    axis = replace(paper_params.axis("inner_az"), fitted_with=record)
    path = save_parameters(paper_params.with_axis("inner_az", axis), tmp_path / "p.yaml")
    loaded = load_parameters(path)
    assert loaded.axis("inner_az").fitted_with == record
    assert loaded.axis("inner_el").fitted_with is None
    text = path.read_text()
    assert text.count("fitted_with:") == 1 and "substeps: 7" in text


def test_identify_records_the_model_and_timing_it_fitted_with():
    import numpy as np

    from isp_twin.identification.fit import IdentificationResult, to_axis_params
    from isp_twin.identification.read_out import Timing, recorded_model
    from isp_twin.model.parameters import RateParams
    from isp_twin.model.substep_model import Integration
    from isp_twin.resources import default_parameters_path

    prior = load_parameters(default_parameters_path()).axis("inner_az")
    rate = prior.rate_params()
    integration, timing = Integration(6, True, False, True), Timing(0.75, True)
    result = IdentificationResult(
        rate=RateParams.from_vector(rate.to_vector()),
        ci95=np.full(RATE_LAYOUT.size, np.nan),
        identifiable=np.zeros(RATE_LAYOUT.size, dtype=bool),
        visits=np.zeros(4, dtype=int),
        regime_identified=(True,) * 4,
        rmse_train={},
        cost=0.0,
        history=(),
        initial_cost=0.0,
        rho=0.0,
        evaluations=0,
        wall_time_s=0.0,
        status="",
        timing=timing,
        integration=integration,
    )
    record = to_axis_params(result, prior).fitted_with
    assert recorded_model(record) == (integration, timing)
