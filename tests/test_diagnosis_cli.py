"""`isp-twin diagnose` end to end: files in, updated parameter file, report,
recording and JSON out; the updated file makes both engines reproduce the data."""

from __future__ import annotations

import json

import numpy as np
import pytest

from isp_twin.cli import main
from isp_twin.diagnosis.synthetic import excitation, make_run
from isp_twin.identification.measured import load_measured, save_measured
from isp_twin.model.axis_model import simulate
from isp_twin.model.effects import make_effect
from isp_twin.model.parameters import EffectSpec, load_parameters
from isp_twin.resources import default_parameters_path
from isp_twin.vocabulary import REGIMES

DT = 1e-3
NOISE = 0.003
AXIS = "outer_az"  # no +-4 deg stop: the run can cover several cogging periods
TRUTH = EffectSpec("cogging", {"amplitude_rad_s2": 4.0, "period_rad": 0.15, "phase_rad": 0.3})


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    folder = tmp_path_factory.mktemp("diag")
    params = load_parameters(default_parameters_path())
    rate = params.axis(AXIS).rate_params()
    rng = np.random.default_rng(7)
    files = []
    for i in range(3):
        run = make_run(f"run{i}", rate, 0.8 * excitation(rng, 1500, DT), DT, rng, [TRUTH], NOISE)
        files.append(save_measured(run, folder / f"run{i}.csv"))
    out = folder / "out" / "updated.yaml"
    report = folder / "report"
    code = main(
        [
            "diagnose",
            str(files[0]),
            str(files[1]),
            "--holdout",
            str(files[2]),
            "--params",
            str(default_parameters_path()),
            "--axis",
            AXIS,
            "--candidates",
            "cogging,unbalance,cable_spring",
            "--max-rounds",
            "1",
            "--substeps",
            "1",  # the runs are made by Eq. 6 itself
            "--out",
            str(out),
            "--report",
            str(report),
            "--json",
            str(folder / "result.json"),
        ]
    )
    return code, folder, files, out, report


def test_the_command_writes_the_parameter_file_report_recording_and_json(case):
    code, folder, _, out, report = case
    assert code == 0
    result = json.loads((folder / "result.json").read_text())
    assert {
        "selected_effect",
        "effect_parameters",
        "rmse_before",
        "rmse_after",
        "noise_floor",
        "ranking",
    } <= set(result)
    assert result["selected_effect"] == "cogging"
    assert result["effect_parameters"]["period_rad"] == pytest.approx(0.15, rel=0.01)
    assert result["ranking"][0]["name"] == "cogging"
    effects = load_parameters(out).axis(AXIS).effects
    assert [e.name for e in effects] == ["cogging"]
    md = (report / "updated_diagnosis.md").read_text()
    assert "cogging" in md and "noise floor" in md
    assert (report / "updated_diagnosis.png").stat().st_size > 10_000
    assert (report / "updated_residuals.rrd").stat().st_size > 1_000


def test_the_json_counts_the_final_models_breakaways_and_names_the_untrained(case):
    """The final model's breakaways per regime on the training runs and its
    rests on the held-out run (docs/identification.md "Stop 54"); the named
    regimes are those rested against held out and never broken away from in
    training."""
    _, folder, _, _, _ = case
    result = json.loads((folder / "result.json").read_text())
    counts = result["breakaways"]
    assert set(counts) == {"training_breakaways", "held_out_rests"}
    for role in counts.values():
        assert set(role) == set(REGIMES) and all(n >= 0 for n in role.values())
    assert sum(counts["training_breakaways"].values()) > 0  # the runs start and stop
    named = [b["regime"] for b in result["held_out_breakaways_untrained"]]
    assert named == [
        r
        for r in REGIMES
        if counts["held_out_rests"][r] > 0 and counts["training_breakaways"][r] == 0
    ]


def test_the_fast_model_with_the_updated_file_reproduces_held_out_data(case):
    _, _, files, out, _ = case
    held = load_measured(files[2])
    axis = load_parameters(out).axis(AXIS)
    with_effect = simulate(
        axis.rate_params(),
        held.u,
        DT,
        angle0=held.angle[0],
        effects=[make_effect(e, DT) for e in axis.effects],
    )
    rms = np.sqrt(np.mean((held.omega - with_effect.omega)[50:] ** 2))
    assert rms <= 1.2 * NOISE


def test_the_twin_with_the_updated_file_reproduces_held_out_data(case):
    from isp_twin.model.twin import GIMBALS, Twin

    _, _, files, out, _ = case
    held = load_measured(files[2])

    def twin_rms(params):
        twin = Twin(params)
        twin.reset({})
        i = GIMBALS.index(AXIS)
        command = np.zeros(len(GIMBALS))
        rate = np.zeros(held.u.size)
        for k in range(1, held.u.size):
            command[i] = held.u[k - 1]
            twin.step(command)
            rate[k] = twin.state().rate[i]
        return np.sqrt(np.mean((held.omega - rate)[50:] ** 2))

    updated = twin_rms(load_parameters(out))
    given = twin_rms(load_parameters(default_parameters_path()))
    # Every twin step is an Eq. 6 step (docs/axis_model.md, section 5), the
    # effect included: the twin meets the fast model's bound.
    assert updated <= 1.2 * NOISE, f"twin RMS {updated:.2e} vs noise {NOISE:.2e}"
    assert updated <= 0.25 * given


def test_bad_input_is_one_line_naming_what_and_where(tmp_path, capsys):
    params = str(default_parameters_path())
    assert main(["diagnose", str(tmp_path / "missing.csv"), "--params", params]) == 2
    assert "missing.csv" in capsys.readouterr().err
    rng = np.random.default_rng(0)
    rate = load_parameters(params).axis("inner_az").rate_params()
    data = save_measured(make_run("r", rate, excitation(rng, 300, DT), DT, rng), tmp_path / "r.csv")
    assert (
        main(
            [
                "diagnose",
                str(data),
                "--params",
                params,
                "--candidates",
                "coging",
                "--report",
                str(tmp_path),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "did you mean 'cogging'" in err and err.count("\n") == 1


def test_the_updated_file_records_the_model_and_a_second_diagnosis_uses_it(case, capsys):
    from isp_twin.identification.read_out import recorded_model

    _, folder, files, out, _ = case
    first = json.loads((folder / "result.json").read_text())
    assert first["model_source"].startswith("--substeps")
    record = load_parameters(out).axis(AXIS).fitted_with
    assert record is not None and record.substeps == 1  # what the first run was told
    integration, timing = recorded_model(record)
    assert first["integration"]["substeps_per_sample"] == integration.substeps
    assert first["timing"] == {
        "gyro_average": timing.gyro_average,
        "side_shift_steps": timing.side_shift,
    }

    # The record without the effect (the file with it is diagnosed in
    # test_a_file_whose_axis_carries_an_effect_is_diagnosed_with_it_held).
    from dataclasses import replace

    from isp_twin.model.parameters import save_parameters

    params = load_parameters(out)
    plain = replace(params.axis(AXIS), effects=())
    recorded = save_parameters(params.with_axis(AXIS, plain), folder / "recorded.yaml")

    def again(*extra: str) -> tuple[dict, str]:
        result = folder / f"again{len(extra)}.json"
        argv = ["diagnose", str(files[0]), "--holdout", str(files[2]), "--params", str(recorded)]
        argv += ["--axis", AXIS, "--candidates", "cogging", "--max-rounds", "1"]
        argv += ["--no-recording", "--report", str(folder / "again"), "--json", str(result)]
        argv += ["--out", str(folder / f"again{len(extra)}.yaml")]
        capsys.readouterr()
        assert main([*argv, *extra]) == 0
        return json.loads(result.read_text()), capsys.readouterr().out

    # No --substeps: the file's record, timing included (not chosen again).
    used, _ = again()
    assert used["model_source"] == "parameter file (fitted_with)"
    assert used["integration"]["substeps_per_sample"] == 1
    assert used["timing"] == first["timing"]
    # Another --substeps overrides it, and says so.
    used, text = again("--substeps", "4")
    assert used["integration"]["substeps_per_sample"] == 4
    line = f"--substeps 4 overrides {recorded}: axes.{AXIS}.fitted_with.substeps 1"
    assert line in text and line in used["model_override"]
    # --out writes the model back: diagnose's own where it re-fitted the axis,
    # else the record the unchanged parameters came with.
    for n_extra, m in ((0, 1), (2, 4)):
        written = load_parameters(folder / f"again{n_extra}.yaml").axis(AXIS)
        refitted = written.regimes != plain.regimes or written.effects != plain.effects
        assert written.fitted_with == (plain.fitted_with if not refitted else written.fitted_with)
        assert written.fitted_with.substeps == (m if refitted else 1)


def test_a_file_whose_axis_carries_an_effect_is_diagnosed_with_it_held(case, capsys):
    # The updated file holds the cogging found: a second diagnosis keeps it as
    # part of the model (it once went in as a candidate's parameters: a
    # TypeError traceback) and, with it, finds nothing more to add.
    _, folder, files, out, _ = case
    assert [e.name for e in load_parameters(out).axis(AXIS).effects] == ["cogging"]
    result = folder / "second.json"
    argv = ["diagnose", str(files[0]), "--holdout", str(files[2]), "--params", str(out)]
    argv += ["--axis", AXIS, "--candidates", "torque_offset", "--max-rounds", "1"]
    argv += ["--no-recording", "--report", str(folder / "second"), "--json", str(result)]
    argv += ["--out", str(folder / "second.yaml")]
    assert main(argv) == 0
    capsys.readouterr()
    second = json.loads(result.read_text())
    assert second["selected_effect"] == "none"
    kept = load_parameters(folder / "second.yaml").axis(AXIS).effects
    assert [e.name for e in kept] == ["cogging"]
