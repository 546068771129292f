"""The command line: help texts, and bad input as one line with exit code 2."""

from __future__ import annotations

import json

import pytest

from isp_twin.cli import main
from isp_twin.resources import default_parameters_path

OPEN_LOOP = """\
name: ol_test
kind: open_loop
duration_s: 5.0
parameters: {params}
open_loop:
  axis: inner_az
  command: {{amplitude_digits: 950.0, freq_hz: 0.5, offset_digits: 0.0}}
"""


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    assert len(err.splitlines()) == 1, err
    return err


def test_help_explains_every_subcommand(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for name in ("run", "identify", "diagnose"):
        assert name in out
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    assert "scenario" in capsys.readouterr().out


def test_missing_scenario_file(capsys, tmp_path):
    assert main(["run", str(tmp_path / "nope.yaml")]) == 2
    assert "nope.yaml" in _one_line_error(capsys)


def test_unknown_scenario_key_names_the_key_and_the_nearest(capsys, tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(OPEN_LOOP.format(params="paper_table2").replace("duration_s", "duraton_s"))
    assert main(["run", str(path)]) == 2
    err = _one_line_error(capsys)
    assert "bad.yaml" in err and "duraton_s" in err and "duration_s" in err


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("      Ts: {value: 5.563, ci95: 0.284}\n", "", "inner_az.R+.Ts: missing"),
        ("Tc: {value: 3.176", "Tc: {value: -3.176", "inner_az.R+.Tc: must be positive"),
    ],
)
def test_bad_parameter_file(capsys, tmp_path, old, new, message):
    params = tmp_path / "params.yaml"
    params.write_text(default_parameters_path().read_text().replace(old, new, 1))
    scenario = tmp_path / "s.yaml"
    scenario.write_text(OPEN_LOOP.format(params=params))
    assert main(["run", str(scenario), "--no-recording"]) == 2
    err = _one_line_error(capsys)
    assert "params.yaml" in err and message in err


def test_open_loop_run_writes_json_and_recording(capsys, tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(OPEN_LOOP.format(params="paper_table2"))
    out_json = tmp_path / "m.json"
    rrd = tmp_path / "r.rrd"
    assert main(["run", str(scenario), "--json", str(out_json), "--recording", str(rrd)]) == 0
    payload = json.loads(out_json.read_text())
    assert payload["scenario"] == "ol_test"
    assert payload["parameters_file"].endswith("paper_table2.yaml")
    peaks = payload["open_loop"]["peak_deg_s"]
    assert peaks["R+"] > 0 > peaks["R-"]
    assert rrd.stat().st_size > 0
    printed = capsys.readouterr().out
    assert "11.98" in printed  # the paper's peak is shown beside the twin's


def test_ctrl_c_leaves_a_recording_that_rerun_verifies(tmp_path, ctrl_c_delivered):
    import os
    import signal
    import subprocess
    import sys
    import time

    from isp_twin.output.readback import verify_recording

    scenario = tmp_path / "long.yaml"
    scenario.write_text(
        "name: long\nkind: closed_loop\nduration_s: 600.0\n"
        "turntable:\n  table_yaw: {amplitude_deg: 3.0, freq_hz: 0.16666666666666666}\n"
    )
    rrd = tmp_path / "long.rrd"
    # An interrupt before the time loop (model build, slow on a loaded
    # machine) rightly leaves nothing; then try again, waiting longer.
    # The compiled loop runs these 600 s in a few seconds: interrupt early.
    for delay in (0.5, 1.0, 2.0):
        proc = subprocess.Popen(
            [
                *(sys.executable, "-m", "isp_twin.cli", "run", str(scenario)),
                *("--recording", str(rrd), "--json", str(tmp_path / "long.json")),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
            preexec_fn=ctrl_c_delivered,
        )
        try:
            # "parameters ..." is printed just before the simulation starts.
            for line in proc.stdout:
                if line.startswith("parameters"):
                    break
            time.sleep(delay)
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=60)
        finally:
            proc.kill()
        if err != "isp-twin run: interrupted\n":
            break
        assert not rrd.exists() and not list(tmp_path.glob("*.part"))
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    verify_recording(rrd)
    assert not list(tmp_path.glob("*.part"))
    # The metrics of the partial run say that they are partial.
    assert json.loads((tmp_path / "long.json").read_text())["interrupted"] is True


def test_every_subcommand_module_is_wired_into_the_cli(capsys):
    import importlib
    import pkgutil

    import isp_twin.commands
    from isp_twin.cli import SUBCOMMANDS, build_parser

    with_parser = set()
    for info in pkgutil.iter_modules(isp_twin.commands.__path__):
        module = importlib.import_module(f"isp_twin.commands.{info.name}")
        if hasattr(module, "add_parser"):
            with_parser.add(module)
    assert with_parser == set(SUBCOMMANDS)
    names = build_parser()._subparsers._group_actions[0].choices
    assert sorted(names) == sorted(m.__name__.rsplit(".", 1)[1] for m in SUBCOMMANDS)
