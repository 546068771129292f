"""Honest calibration: the roles of the paper cells, the fit, the labelled table, the commands.

The roles follow from the rig file and the scenarios only; the fit and the
commands are checked with the runs replaced by a known function of the
settings (the simulations are the closed-loop tests' business).
"""

from __future__ import annotations

import json

import pytest

import isp_twin.experiments.calibration as calibration
from isp_twin.cli import main
from isp_twin.experiments.calibration import (
    CellResult,
    Evaluation,
    calibration_markdown,
    cell_roles,
    fit_rig,
)
from isp_twin.experiments.metrics import campaign_stats
from isp_twin.experiments.paper import PAPER_CELLS
from isp_twin.experiments.rig import load_rig, resolve_rig

RIG_FILE = resolve_rig("paper_rig")


def test_the_roles_of_the_paper_rig():
    roles = cell_roles(load_rig(RIG_FILE))
    assert [n for n, r in roles.items() if r.role == "fitted"] == ["table4_1_6Hz_pi"]
    # Table 6's PI row is the fitted cell's run, Table 5's PI row the 0.5 Hz, pi cell's.
    assert (roles["table6_pi"].role, roles["table6_pi"].repeat_of) == ("repeat", "table4_1_6Hz_pi")
    assert (roles["table5_pi"].role, roles["table5_pi"].repeat_of) == ("repeat", "table4_0_5Hz_pi")
    assert roles["table5_pi_nfc"].role == roles["table6_pi_nfc"].role == "shaped"
    assert "notch_freq" in roles["table5_pi_nfc"].shaped_by
    assert [n for n, r in roles.items() if r.role == "validation"] == ["table4_0_5Hz_2pi"]


def test_declaring_a_cell_fitted_in_the_rig_makes_it_fitted(tmp_path):
    text = RIG_FILE.read_text().replace(
        "    cells: [table4_1_6Hz_pi]\n    fit:\n      cells: [table4_1_6Hz_pi]",
        "    cells: [table4_1_6Hz_pi, table4_0_5Hz_2pi]\n"
        "    fit:\n      cells: [table4_1_6Hz_pi, table4_0_5Hz_2pi]",
    )
    rig_path = tmp_path / "rig.yaml"
    rig_path.write_text(text)
    roles = cell_roles(load_rig(rig_path))
    assert roles["table4_0_5Hz_2pi"].role == "fitted"
    assert roles["table4_0_5Hz_2pi"].fitted_knobs == ("gyro_scale",)


def _fake_runs(monkeypatch, j_of):
    """Replace the simulations: J of a run = j_of(cell scenario name, scenario, seed)."""

    def fake(work, jobs, client=None):
        out = {}
        for tag, scenario, seed in work:
            j = j_of(scenario, seed)
            out.setdefault(tag, []).append(
                {"isolation_percent": j, "max_abs_error_deg_s": j / 100, "rms_error_deg_s": j / 300}
            )
        return out

    monkeypatch.setattr(calibration, "_run_many", fake)


def test_the_fit_finds_the_scale_whose_j_matches_the_paper(monkeypatch):
    # J inversely proportional to the gyro scale, equal to the paper's at 70.
    paper = PAPER_CELLS["table4_1_6Hz_pi"].paper_percent
    _fake_runs(monkeypatch, lambda s, seed: paper * 70.0 / s.gyro.scale_count_per_deg_s)
    fit = fit_rig(load_rig(RIG_FILE), n_runs=2)
    assert fit.knobs == ("gyro_scale",) and fit.cells == ("table4_1_6Hz_pi",)
    assert fit.best == {"gyro_scale": 70.0}
    assert min(fit.sse) == pytest.approx(0.0)


def _evaluation(differences: dict[str, float]) -> Evaluation:
    roles = cell_roles(load_rig(RIG_FILE))
    cells = {}
    for name, cell in PAPER_CELLS.items():
        j = cell.paper_percent + differences.get(name, 0.0)
        stats = campaign_stats([j, j])
        cells[name] = CellResult(cell, roles[name], stats, 0.5, 0.1, stats if cell.nfc else None)
    return Evaluation("paper_rig", {}, 2, 1, cells)


def _row(text: str, cell: str) -> list[str]:
    line = next(x for x in text.splitlines() if x.startswith(f"| {cell} |"))
    return [c.strip() for c in line.strip("|").split("|")]


def test_each_difference_stands_in_the_column_of_its_role():
    text = calibration_markdown(_evaluation({"table6_pi": 1.25, "table4_0_5Hz_2pi": -0.5}))
    columns = ["fitted", "repeat", "shaped", "validation"]
    for name, role in cell_roles(load_rig(RIG_FILE)).items():
        row = _row(text, name)
        filled = [col for col, value in zip(columns, row[3:7]) if value]
        assert filled == [role.role], name
    assert _row(text, "table6_pi")[4].startswith("+1.25 (= table4_1_6Hz_pi, fitted)")
    assert _row(text, "table4_0_5Hz_2pi")[6] == "-0.50"


def test_targets_say_met_or_not_met_by_the_issues_tolerances():
    ok = calibration_markdown(_evaluation({"table4_0_5Hz_pi": 2.9, "table5_pi_nfc": -1.9}))
    assert _row(ok, "table4_0_5Hz_pi")[7] == "+-3: met"
    assert _row(ok, "table5_pi_nfc")[7] == "+-2: met"
    off = calibration_markdown(_evaluation({"table4_0_5Hz_pi": 3.1, "table5_pi_nfc": -2.1}))
    assert _row(off, "table4_0_5Hz_pi")[7] == "+-3: **NOT met**"
    assert _row(off, "table5_pi_nfc")[7] == "+-2: **NOT met**"
    assert "table5_pi_nfc (shaped by notch_freq" in off


def test_calibrate_fits_then_reports_every_cell_with_its_role(monkeypatch, tmp_path, capsys):
    paper = PAPER_CELLS["table4_1_6Hz_pi"].paper_percent
    # Every cell's J scales with 1/scale and equals the paper's at 60 on the fitted cell.
    _fake_runs(monkeypatch, lambda s, seed: paper * 60.0 / s.gyro.scale_count_per_deg_s)
    out, js = tmp_path / "cal.md", tmp_path / "cal.json"
    argv = ["calibrate", "-n", "2", "--jobs", "1", "--output", str(out), "--json", str(js)]
    assert main(argv) == 0
    doc = json.loads(js.read_text())
    assert doc["fit"]["best"] == {"gyro_scale": 60.0}
    assert doc["settings"] == {"gyro.scale_count_per_deg_s": 60.0}
    assert doc["cells"]["table4_1_6Hz_pi"]["twin"]["average"] == pytest.approx(paper)
    assert doc["cells"]["table6_pi"]["repeat_of"] == "table4_1_6Hz_pi"
    assert {c["role"] for c in doc["cells"].values()} == {
        "fitted",
        "repeat",
        "shaped",
        "validation",
    }
    assert "twin_exact_nfc_model" in doc["cells"]["table6_pi_nfc"]
    assert out.read_text().startswith("# Calibration and paper vs twin")
    assert "Fitted: gyro_scale = 60" in capsys.readouterr().out


def test_report_does_not_fit(monkeypatch, tmp_path):
    _fake_runs(monkeypatch, lambda s, seed: s.gyro.scale_count_per_deg_s / 3)
    js = tmp_path / "r.json"
    assert main(["report", "-n", "1", "--jobs", "1", "--json", str(js)]) == 0
    doc = json.loads(js.read_text())
    assert "fit" not in doc and doc["settings"] == {}
    scale = load_rig(RIG_FILE).knob("gyro_scale").value
    assert doc["cells"]["table4_1_6Hz_pi"]["twin"]["average"] == pytest.approx(scale / 3)


def test_a_bad_rig_stops_calibrate_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(RIG_FILE.read_text().replace("    value: 70.0\n", "    value: 500.0\n", 1))
    assert main(["calibrate", "--rig", str(bad), "-n", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "gyro_scale.value" in err
