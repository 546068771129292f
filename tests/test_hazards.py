"""The hazards of issue 12, one reproducing test each (the refusals are also
rows of test_hostile_input.py), and the real-world files that must work."""

from __future__ import annotations

import io
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hostile_world import CLOSED_LOOP, OPEN_LOOP, good_table, write_csv

from isp_twin.cli import main
from isp_twin.errors import OutputError
from isp_twin.output.files import staged_path, transaction
from isp_twin.resources import default_parameters_path

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture()
def ol(tmp_path) -> Path:
    path = tmp_path / "ol.yaml"
    path.write_text(OPEN_LOOP)
    return path


def _no_part_files(folder: Path) -> bool:
    return not list(folder.rglob("*.part"))


# ---------------------------------------------------------------- special destinations


def test_json_to_dev_full_fails_in_one_line_and_keeps_the_device(ol, capsys):
    assert main(["run", str(ol), "--no-recording", "--json", "/dev/full"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "/dev/full" in err and "No space left" in err
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


def test_a_device_failing_leaves_the_other_outputs_unwritten(ol, tmp_path, capsys):
    rrd = tmp_path / "r.rrd"
    assert main(["run", str(ol), "--recording", str(rrd), "--json", "/dev/full"]) == 2
    assert not rrd.exists() and _no_part_files(tmp_path)


def test_json_through_a_symlink_replaces_the_target_and_keeps_the_link(ol, tmp_path, capsys):
    target = tmp_path / "real.json"
    target.write_text("old\n")
    link = tmp_path / "link.json"
    link.symlink_to(target.name)
    assert main(["run", str(ol), "--no-recording", "--json", str(link)]) == 0
    assert link.is_symlink() and os.readlink(link) == target.name
    assert json.loads(target.read_text())["scenario"] == "tiny_ol"
    assert _no_part_files(tmp_path)


def test_json_into_a_fifo_is_written_through_to_its_reader(ol, tmp_path, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # a reader is there
    try:
        assert main(["run", str(ol), "--no-recording", "--json", str(fifo)]) == 0
        got = os.read(reader, 1 << 16).decode()
    finally:
        os.close(reader)
    assert json.loads(got)["scenario"] == "tiny_ol"
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


def test_json_into_a_fifo_without_reader_fails_instead_of_hanging(ol, tmp_path, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert main(["run", str(ol), "--no-recording", "--json", str(fifo)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no reader" in err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


def test_json_dash_writes_only_the_json_to_stdout(ol, capsys):
    assert main(["run", str(ol), "--no-recording", "--json", "-"]) == 0
    out, err = capsys.readouterr()
    payload = json.loads(out)  # nothing but the document
    assert payload["scenario"] == "tiny_ol"
    assert "scenario tiny_ol" in err  # the human report moved to stderr


# ---------------------------------------------------------------- transactions


def test_a_transaction_writes_all_files_or_none(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "new" / "b.txt"
    with pytest.raises(RuntimeError), transaction():
        with staged_path(a) as tmp:
            tmp.write_text("a")
        with staged_path(b) as tmp:
            tmp.write_text("b")
        assert not a.exists()  # nothing reaches its target before the end
        raise RuntimeError("the command failed after writing")
    assert not a.exists() and not b.exists() and not (tmp_path / "new").exists()
    assert _no_part_files(tmp_path)
    with transaction():
        with staged_path(a) as tmp:
            tmp.write_text("a")
        with staged_path(b) as tmp:
            tmp.write_text("b")
    assert a.read_text() == "a" and b.read_text() == "b"
    assert _no_part_files(tmp_path)


def test_a_failing_write_inside_a_transaction_leaves_no_output(tmp_path):
    a = tmp_path / "a.txt"
    with pytest.raises(OutputError), transaction():
        with staged_path(a) as tmp:
            tmp.write_text("a")
        with staged_path("/dev/full") as tmp:
            tmp.write_text("x" * 100)
    assert not a.exists() and _no_part_files(tmp_path)


def test_identify_checks_its_json_before_writing_its_parameter_file(tmp_path, capsys):
    data = write_csv(tmp_path / "d.csv", good_table())
    out = tmp_path / "p.yaml"
    argv = ["identify", str(data), "--out", str(out), "--json", str(tmp_path / "afile" / "x")]
    (tmp_path / "afile").write_text("")
    assert main(argv) == 2
    assert not out.exists() and not (tmp_path / "p_report.md").exists()


# ---------------------------------------------------------------- processes


def _cli(*args: str, **kwargs) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.Popen(
        [sys.executable, "-m", "isp_twin.cli", *args],
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        **kwargs,
    )


def test_a_closed_pipe_ends_the_command_quietly(ol):
    """`isp-twin run ... | head -1`: the reader is gone before the output comes."""
    proc = _cli("run", str(ol), "--no-recording", stdout=subprocess.PIPE)
    proc.stdout.close()  # as `head` does once it has its line
    err = proc.stderr.read()
    proc.wait(timeout=120)
    assert proc.returncode == 141
    assert err == ""


def test_benchmark_without_its_data_exits_with_the_cli_code(tmp_path):
    script = REPO / "benchmarks" / "identify_hsm150.py"
    proc = subprocess.run(
        [sys.executable, str(script), "--data", str(tmp_path / "absent"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
        timeout=120,
    )
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "exit 2" in proc.stdout


# ---------------------------------------------------------------- real-world files


def test_a_csv_with_a_byte_order_mark_loads(tmp_path):
    from isp_twin.identification.measured import load_measured

    plain = write_csv(tmp_path / "plain.csv", good_table())
    bom = tmp_path / "excel.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    a, b = load_measured(plain), load_measured(bom)
    assert np.array_equal(a.omega, b.omega) and np.array_equal(a.t, b.t)


def test_a_scenario_with_a_byte_order_mark_loads(tmp_path):
    from isp_twin.experiments.scenario import load_scenario

    path = tmp_path / "bom.yaml"
    path.write_bytes(b"\xef\xbb\xbf" + OPEN_LOOP.encode())
    assert load_scenario(path).name == "tiny_ol"


def _drifting(path: Path, ppm: float) -> Path:
    table = good_table(400)
    table[:, 0] *= 1 + ppm * 1e-6
    return write_csv(path, table)


def test_a_clock_drifting_30_ppm_passes_identify_and_diagnose_alike(tmp_path):
    from isp_twin.estimation.simulation_error import stack_runs
    from isp_twin.identification.measured import (
        SAMPLE_PERIOD_TOLERANCE,
        check_sample_period,
        load_measured,
    )

    runs = [load_measured(_drifting(tmp_path / f"d{p}.csv", p)) for p in (0, 30, -30)]
    lines = check_sample_period(runs, 1e-3, "paper")
    assert lines[1].endswith("(+30 ppm)") and lines[2].endswith("(-30 ppm)")
    stack_runs(runs)  # the diagnosis stacks runs of slightly different periods
    too_slow = load_measured(_drifting(tmp_path / "slow.csv", 2e6 * SAMPLE_PERIOD_TOLERANCE))
    from isp_twin.errors import DataError

    with pytest.raises(DataError, match=r"slow.csv: measured sample period .* \+2 % off"):
        check_sample_period([too_slow], 1e-3, "paper")


def test_identify_reports_the_measured_period_of_a_drifting_log(tmp_path, capsys):
    data = _drifting(tmp_path / "drift.csv", 30)
    argv = ["identify", str(data), "--out", str(tmp_path / "p.yaml"), "--no-report"]
    argv += ["--generations", "0", "--refine-evaluations", "5", "--json", str(tmp_path / "p.json")]
    assert main(argv) == 0
    assert "drift: sample period 0.00100003 s (+30 ppm)" in capsys.readouterr().out
    summary = json.loads((tmp_path / "p.json").read_text())
    assert summary["sample_period_s"]["drift"] == pytest.approx(1.00003e-3, rel=1e-9)


def test_training_and_validation_files_with_one_name_get_their_own_figures(tmp_path, capsys):
    a, b = tmp_path / "paper1", tmp_path / "paper2"
    a.mkdir(), b.mkdir()
    write_csv(a / "eq7.csv", good_table())
    other = good_table()
    other[:, 2] *= 1.5
    write_csv(b / "eq7.csv", other)
    out = tmp_path / "id.yaml"
    argv = ["identify", str(a / "eq7.csv"), "--validate", str(b / "eq7.csv"), "--out", str(out)]
    argv += ["--generations", "0", "--refine-evaluations", "5", "--json", str(tmp_path / "id.json")]
    assert main(argv) == 0
    figures = sorted(p.name for p in tmp_path.glob("id_report_*.png"))
    assert figures == ["id_report_paper1_eq7.png", "id_report_paper2_eq7.png"]
    summary = json.loads((tmp_path / "id.json").read_text())
    assert list(summary["rmse_validation"]) == ["paper2_eq7"]


# ---------------------------------------------------------------- YAML numbers


def test_scientific_notation_is_a_number_in_scenarios(tmp_path):
    from isp_twin.experiments.scenario import load_scenario

    path = tmp_path / "sci.yaml"
    text = OPEN_LOOP.replace("duration_s: 0.05", "duration_s: 5e-2")
    path.write_text(text.replace("amplitude_digits: 950.0", "amplitude_digits: 1e3"))
    s = load_scenario(path)
    assert s.duration_s == 0.05 and s.open_loop.command.amplitude_digits == 1000.0
    path.write_text(CLOSED_LOOP.replace("name: tiny_cl", "name: tiny_cl\nseed: 1e1"))
    assert load_scenario(path).seed == 10


def test_scientific_notation_is_a_number_in_parameter_files(tmp_path):
    from isp_twin.model.parameters import load_parameters

    text = default_parameters_path().read_text()
    assert "sample_time_s: 0.001" in text
    path = tmp_path / "p.yaml"
    path.write_text(text.replace("sample_time_s: 0.001", "sample_time_s: 1e-3"))
    assert load_parameters(path).sample_time_s == 1e-3


def test_scientific_notation_is_a_number_in_data_descriptions(tmp_path):
    from isp_twin.identification.measured import load_data_description

    path = tmp_path / "d.yaml"
    path.write_text("columns: {t: t, u: u, omega: {column: omega, scale: 1e0}}\n")
    path.write_text(path.read_text() + "initial_angle_deg: 2e0\n")
    mapping = load_data_description(path)
    assert mapping.initial_angle_deg == 2.0 and mapping.columns["omega"].scale == 1.0


def test_strings_that_only_look_numeric_stay_strings(tmp_path):
    from isp_twin.input_files import load_yaml

    path = tmp_path / "x.yaml"
    path.write_text("a: 1e4\nb: e4\nc: 1e\nd: '1e4'\ne: 12\n")
    raw, _ = load_yaml(path, "test file", OutputError)
    assert raw == {"a": 1e4, "b": "e4", "c": "1e", "d": "1e4", "e": 12}


# ---------------------------------------------------------------- outputs say their units


def test_run_json_states_its_units(tmp_path, capsys):
    cl = tmp_path / "cl.yaml"
    cl.write_text(CLOSED_LOOP)
    js = tmp_path / "cl.json"
    assert main(["run", str(cl), "--no-recording", "--json", str(js)]) == 0
    payload = json.loads(js.read_text())
    assert payload["interrupted"] is False
    for axis in payload["metrics"].values():
        assert set(axis) <= set(payload["units"])
    assert payload["units"]["isolation_percent"].startswith("%")


def test_campaign_json_states_its_units(tmp_path, capsys):
    cl = tmp_path / "cl.yaml"
    cl.write_text(CLOSED_LOOP)
    js = tmp_path / "c.json"
    assert main(["campaign", str(cl), "-n", "2", "--jobs", "1", "--json", str(js)]) == 0
    payload = json.loads(js.read_text())
    stats = payload["metrics"]["inner_az"]
    keys = set(stats["PI"]) | {"relative_reduction_percent"}
    assert keys <= set(payload["units"])
    assert "fraction" in payload["units"]["variance"] and payload["units"]["average"] == "%"


def test_report_json_states_its_units():
    from isp_twin.experiments.calibration import CellResult, Evaluation, cell_roles, evaluation_json
    from isp_twin.experiments.metrics import campaign_stats
    from isp_twin.experiments.paper import PAPER_CELLS
    from isp_twin.experiments.rig import load_rig, resolve_rig

    roles = cell_roles(load_rig(resolve_rig("paper_rig")))
    stats = campaign_stats([10.0, 12.0])
    cells = {
        n: CellResult(
            c, roles[n], stats, 0.5, 0.1, stats if c.nfc else None, 0.1 if c.nfc else None
        )
        for n, c in PAPER_CELLS.items()
    }
    payload = json.loads(json.dumps(evaluation_json(Evaluation("paper_rig", {}, 2, 1, cells))))
    for cell in payload["cells"].values():
        numbers = {k for k, v in cell.items() if isinstance(v, float)}
        assert numbers <= set(payload["units"])
        assert set(cell["twin"]) <= set(payload["units"])
    assert payload["cells"]["table5_pi"]["twin"]["average"] == 11.0


# ---------------------------------------------------------------- progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_prints_plain_lines_when_not_on_a_terminal():
    import time

    from isp_twin.commands.progress import working

    stream = io.StringIO()
    with working("diagnose inner_az", stream, interval_s=0.05):
        time.sleep(0.3)
    lines = stream.getvalue().splitlines()
    assert len(lines) >= 2 and all(line.startswith("diagnose inner_az: 0:00") for line in lines)
    assert "\r" not in stream.getvalue()


def test_progress_rewrites_one_line_on_a_terminal():
    import time

    from isp_twin.commands.progress import working

    stream = _Terminal()
    with working("campaign x", stream, interval_s=0.05):
        time.sleep(0.3)
    text = stream.getvalue()
    assert text.count("\r") >= 2 and text.endswith("\n") and text.count("\n") == 1


def test_a_quick_command_prints_no_progress(tmp_path):
    from isp_twin.commands.progress import working

    stream = io.StringIO()
    with working("report", stream, interval_s=5.0):
        pass
    assert stream.getvalue() == ""


# ---------------------------------------------------------------- the documented real-data example


def _documented_identify_command() -> list[str]:
    """The `isp-twin identify examples/hsm150/...` command of docs/usage.md, as argv."""
    import shlex

    text = (REPO / "docs" / "usage.md").read_text()
    start = text.index("    isp-twin identify examples/hsm150/")
    block = text[start : text.index("\n\n", start)]
    return shlex.split(block.replace("\\\n", " "))[1:]


def test_the_documented_real_data_example_runs_from_the_shipped_files(tmp_path, capsys):
    argv = _documented_identify_command()
    (tmp_path / "examples").symlink_to(REPO / "examples")  # run "from the repository root"
    old = os.getcwd()
    os.chdir(tmp_path)
    try:
        code = main(argv)
    finally:
        os.chdir(old)
    out = capsys.readouterr().out
    assert code == 0
    assert "identified inner_az regimes R+" in out
    from isp_twin.model.parameters import load_parameters

    axis = load_parameters(tmp_path / "hsm150.yaml").axis("inner_az")
    assert axis.identified == (True, False, False, False)
    # The torque-driven motor: Ke stays near the prior's 1, a is a stable pole.
    assert 0.99 < axis.regime("R+").a < 1.0


def test_a_viewer_that_fails_does_not_undo_the_recording(ol, tmp_path, capsys):
    rrd, js = tmp_path / "r.rrd", tmp_path / "r.json"
    argv = ["run", str(ol), "--recording", str(rrd), "--json", str(js)]
    assert main([*argv, "--connect", "rerun+http://127.0.0.1:1/proxy"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the recording was saved" in err
    assert rrd.is_file() and js.is_file() and _no_part_files(tmp_path)
