"""A parameter file records the angle its rate parameters were fitted on
(``fitted_with.side_source``), and `diagnose` reads the half-plane from that
angle unless ``--side`` says otherwise (stop 36: a file re-identified on the
resolver's angle was diagnosed on the fused one)."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from isp_twin.cli import main
from isp_twin.diagnosis.synthetic import excitation, make_run
from isp_twin.errors import ParameterError
from isp_twin.identification.fit import Settings, to_axis_params
from isp_twin.identification.measured import save_measured
from isp_twin.identification.read_out import Timing, fitted_with
from isp_twin.model.parameters import load_parameters, save_parameters
from isp_twin.model.substep_model import DEFAULT_INTEGRATION
from isp_twin.resources import default_parameters_path

AXIS = "inner_az"
DT = 1e-3


def _file_with_side(folder, side: str | None, name: str = "p.yaml"):
    """The default parameters, the axis recorded as fitted on `side` (None: no key)."""
    params = load_parameters(default_parameters_path())
    record = fitted_with(DEFAULT_INTEGRATION, Timing(), side or "measured")
    path = save_parameters(
        params.with_axis(AXIS, replace(params.axis(AXIS), fitted_with=record)), folder / name
    )
    if side is None:  # a file written before the key existed
        text = re.sub(r"\n *side_source: measured\n", "\n", path.read_text())
        assert "side_source" not in text
        path.write_text(text)
    return path


@pytest.mark.parametrize("side", ["raw", "right", "measured", None])
def test_the_record_keeps_the_side_and_an_old_file_reads_measured(tmp_path, side):
    record = load_parameters(_file_with_side(tmp_path, side)).axis(AXIS).fitted_with
    assert record.side_source == (side or "measured")


def test_an_unknown_side_in_the_record_names_its_key(tmp_path):
    path = _file_with_side(tmp_path, "raw")
    path.write_text(path.read_text().replace("side_source: raw", "side_source: fused"))
    with pytest.raises(ParameterError, match=r"fitted_with\.side_source.*'fused'"):
        load_parameters(path)


def test_identify_records_the_side_it_read():
    prior = load_parameters(default_parameters_path()).axis(AXIS)
    rate = prior.rate_params().to_vector()
    result = SimpleNamespace(
        vector=rate,
        ci95=np.full_like(rate, np.nan),
        integration=DEFAULT_INTEGRATION,
        timing=Timing(0.25, True),
        settings=Settings(side_source="raw"),
        regime_identified=(True,) * 4,
    )
    record = to_axis_params(result, prior).fitted_with
    assert (record.side_source, record.side_shift_steps, record.gyro_average) == ("raw", 0.25, True)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("side")
    rate = load_parameters(default_parameters_path()).axis(AXIS).rate_params()
    rng = np.random.default_rng(3)
    files = [
        save_measured(
            make_run(f"r{i}", rate, 0.8 * excitation(rng, 1200, DT), DT, rng), folder / f"r{i}.csv"
        )
        for i in range(2)
    ]
    return folder, files


def _diagnose(folder, files, params, tag: str, *extra: str) -> tuple[int, dict, str]:
    out = folder / f"{tag}.json"
    argv = ["diagnose", str(files[0]), "--holdout", str(files[1]), "--params", str(params)]
    argv += ["--axis", AXIS, "--candidates", "cogging", "--max-rounds", "1", "--no-recording"]
    argv += [
        "--report",
        str(folder / tag),
        "--json",
        str(out),
        "--out",
        str(folder / f"{tag}_out.yaml"),
    ]
    code = main([*argv, *extra])
    return code, (json.loads(out.read_text()) if code == 0 else {}), str(folder / f"{tag}_out.yaml")


def test_diagnose_reads_the_half_plane_the_file_was_fitted_on(runs, capsys):
    folder, files = runs
    raw_file = _file_with_side(folder, "raw", "raw.yaml")
    code, used, out = _diagnose(folder, files, raw_file, "raw")
    assert code == 0 and used["side_angle"] == "resolver" and "side_override" not in used
    # The file written back says the same, whether diagnose refitted the axis or not.
    assert load_parameters(out).axis(AXIS).fitted_with.side_source == "raw"
    # --side overrides the record, and says so.
    capsys.readouterr()
    code, used, _ = _diagnose(folder, files, raw_file, "over", "--side", "right")
    text = capsys.readouterr().out
    line = "--side right overrides"
    assert code == 0 and used["side_angle"] == "right"
    assert line in text and line in used["side_override"] and "side_source raw" in text


def test_a_side_diagnose_cannot_read_is_one_line_and_exit_2(runs, capsys):
    folder, files = runs
    wrap_file = _file_with_side(folder, "wrap", "wrap.yaml")
    capsys.readouterr()
    code, _, out = _diagnose(folder, files, wrap_file, "wrap")
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "fitted_with.side_source" in err and "'wrap'" in err and "--side" in err
    assert not (folder / "wrap.json").exists() and not (folder / "wrap_out.yaml").exists()
