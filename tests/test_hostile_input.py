"""Hostile input through the CLI entry point: every case exits 2 with one line
on stderr, no traceback, and leaves no output and no temporary file behind.

The table covers the classes of issue 12: unreadable inputs (encoding,
permissions, a folder) in every input slot; every output option aimed at an
awkward destination (read-only folder, a place no one may write, an existing
folder, below a file, an input, a read-only file, a socket, a link loop,
standard output where a file is needed, two outputs on one file, a read-only
working directory for the default folders); out-of-range options (NaN, inf,
negative) of every command; invalid scenarios and data files; refused option
combinations. Cases run in process, as user `nobody` when the suite runs as
root (see hostile_world.py).
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hostile_world import (
    BAD_TEXT,
    build_world,
    good_table,
    import_lazy_modules,
    make_case_dir,
    release,
    snapshot,
    unprivileged,
    working_directory,
    write_csv,
)

from isp_twin.cli import main


@dataclass(frozen=True)
class Case:
    """One hostile invocation: `argv` with {W} (shared inputs) and {C} (the
    case's own folder) filled in; `cwd` relative to {C}."""

    id: str
    argv: tuple[str, ...]
    cwd: str = "ok"
    expect: str = ""  # a fragment the message must hold (case-insensitive)


CASES: list[Case] = []


def case(id_: str, *argv: str, cwd: str = "ok", expect: str = "") -> None:
    CASES.append(Case(id_, tuple(argv), cwd, expect))


#: What the message says for each kind of unreadable input.
INPUT_MESSAGES = {
    "binary": "is not UTF-8 text",
    "latin1": "line 1: not UTF-8: byte 0xe9",
    "utf16": "is not UTF-8 text",
    "nul": "NUL byte",
    "bad_utf8_line3": "line 3",
    "directory": "is a directory",
    "unreadable": "permission denied",
}


# ---------------------------------------------------------------- unreadable inputs
# Each input slot of each command, given a file it cannot read as text.
SCENARIO_SLOTS = {
    "run.scenario": ("run", "{X}", "--no-recording"),
    "run.params": ("run", "{W}/ol.yaml", "--params", "{X}", "--no-recording"),
    "campaign.scenario": ("campaign", "{X}", "-n", "1", "--jobs", "1"),
    "campaign.params": ("campaign", "{W}/cl.yaml", "--params", "{X}", "-n", "1", "--jobs", "1"),
    "identify.prior": ("identify", "{W}/good.csv", "--prior", "{X}", "--out", "{C}/ok/p.yaml"),
    "identify.describe": (
        "identify",
        "{W}/good.csv",
        "--describe",
        "{X}",
        "--out",
        "{C}/ok/p.yaml",
    ),
    "diagnose.params": ("diagnose", "{W}/good.csv", "--params", "{X}", "--out", "{C}/ok/d.yaml"),
    "diagnose.describe": (
        "diagnose",
        "{W}/good.csv",
        "--params",
        "{W}/params.yaml",
        "--describe",
        "{X}",
        "--out",
        "{C}/ok/d.yaml",
    ),
    "generate.params": ("generate", "--out", "{C}/ok/gen", "--params", "{X}"),
}
DATA_SLOTS = {
    "identify.data": ("identify", "{X}", "--out", "{C}/ok/p.yaml"),
    "identify.validate": (
        "identify",
        "{W}/good.csv",
        "--validate",
        "{X}",
        "--out",
        "{C}/ok/p.yaml",
    ),
    "diagnose.data": ("diagnose", "{X}", "--params", "{W}/params.yaml", "--out", "{C}/ok/d.yaml"),
    "diagnose.holdout": (
        "diagnose",
        "{W}/good.csv",
        "--params",
        "{W}/params.yaml",
        "--holdout",
        "{X}",
        "--out",
        "{C}/ok/d.yaml",
    ),
}
for slots, ext in ((SCENARIO_SLOTS, "yaml"), (DATA_SLOTS, "csv")):
    for slot, argv in slots.items():
        for bad in BAD_TEXT:
            case(
                f"input-{bad}-{slot}",
                *(a.replace("{X}", f"{{W}}/bad_{bad}.{ext}") for a in argv),
                expect=INPUT_MESSAGES[bad],
            )
        case(
            f"input-missing-{slot}",
            *(a.replace("{X}", f"{{W}}/absent.{ext}") for a in argv),
            expect="absent",
        )

# ---------------------------------------------------------------- output destinations
# Each output option, aimed at a destination it cannot or must not write.
OUTPUT_SLOTS = {
    # option: (argv with {O}, extension, an input of the command or None)
    "run.json": (("run", "{W}/ol.yaml", "--no-recording", "--json", "{O}"), "json", "{W}/ol.yaml"),
    "run.recording": (("run", "{W}/ol.yaml", "--recording", "{O}"), "rrd", "{W}/ol.yaml"),
    "identify.out": (("identify", "{W}/good.csv", "--out", "{O}"), "yaml", "{W}/good.csv"),
    "identify.report": (
        ("identify", "{W}/good.csv", "--out", "{C}/ok/p.yaml", "--report", "{O}"),
        "md",
        "{W}/good.csv",
    ),
    "identify.json": (
        ("identify", "{W}/good.csv", "--out", "{C}/ok/p.yaml", "--json", "{O}"),
        "json",
        "{W}/good.csv",
    ),
    "diagnose.out": (
        ("diagnose", "{W}/good.csv", "--params", "{W}/params.yaml", "--out", "{O}"),
        "yaml",
        "{W}/params.yaml",
    ),
    "diagnose.recording": (
        (
            "diagnose",
            "{W}/good.csv",
            "--params",
            "{W}/params.yaml",
            "--out",
            "{C}/ok/d.yaml",
            "--recording",
            "{O}",
        ),
        "rrd",
        "{W}/good.csv",
    ),
    "diagnose.json": (
        (
            "diagnose",
            "{W}/good.csv",
            "--params",
            "{W}/params.yaml",
            "--out",
            "{C}/ok/d.yaml",
            "--json",
            "{O}",
        ),
        "json",
        "{W}/good.csv",
    ),
    "campaign.json": (
        ("campaign", "{W}/cl.yaml", "-n", "1", "--jobs", "1", "--json", "{O}"),
        "json",
        "{W}/cl.yaml",
    ),
    "report.output": (("report", "-n", "1", "--jobs", "1", "--output", "{O}"), "md", None),
    "report.json": (("report", "-n", "1", "--jobs", "1", "--json", "{O}"), "json", None),
}
DESTINATIONS = {
    # kind: (destination, message fragment)
    "read-only-dir": ("{C}/ro/x.{ext}", "cannot write in"),
    "read-only-dir-subfolder": ("{C}/ro/new/x.{ext}", "cannot write in"),
    "proc": ("/proc/isp_twin_x.{ext}", "cannot write in /proc"),
    "existing-dir": ("{C}/adir", "is a directory"),
    "below-a-file": ("{C}/afile/x.{ext}", "not a directory"),
    "read-only-file": ("{C}/rofile.{ext}", "read-only"),
    "socket": ("{C}/sock", "socket"),
    "link-loop": ("{C}/loop", "link loop"),
    "empty": ("", "empty path"),
}
for slot, (argv, ext, an_input) in OUTPUT_SLOTS.items():
    for dest, (template, message) in DESTINATIONS.items():
        target = template.replace("{ext}", ext)
        case(f"output-{dest}-{slot}", *(a.replace("{O}", target) for a in argv), expect=message)
    if an_input is not None:
        case(
            f"output-is-input-{slot}",
            *(a.replace("{O}", an_input) for a in argv),
            expect="is one of the inputs",
        )
    if not slot.endswith(".json"):
        case(
            f"output-stdout-{slot}",
            *(a.replace("{O}", "-") for a in argv),
            expect="standard output",
        )

# Folder options.
for slot, argv in {
    "generate.out": ("generate", "--out", "{O}"),
    "diagnose.report": (
        "diagnose",
        "{W}/good.csv",
        "--params",
        "{W}/params.yaml",
        "--report",
        "{O}",
    ),
}.items():
    for dest, target in {
        "existing-file": "{C}/afile",
        "read-only-dir": "{C}/ro",
        "read-only-dir-subfolder": "{C}/ro/new",
        "below-a-file": "{C}/afile/sub",
        "proc": "/proc/isp_twin_dir",
    }.items():
        case(f"folder-{dest}-{slot}", *(a.replace("{O}", target) for a in argv))

# Default output folders in a read-only working directory.
case(
    "default-recordings-in-read-only-cwd",
    "run",
    "{W}/ol.yaml",
    cwd="ro",
    expect="--recording recordings/tiny",
)
case(
    "default-diagnosis-report-in-read-only-cwd",
    "diagnose",
    "{W}/good.csv",
    "--params",
    "{W}/params.yaml",
    cwd="ro",
    expect="--report diagnosis_report/",
)
case(
    "default-identify-report-beside-out-in-read-only-dir",
    "identify",
    "{W}/good.csv",
    "--out",
    "p.yaml",
    cwd="ro",
    expect="cannot write in",
)

# Two outputs on one file; an output that is an input (in several spellings).
case(
    "same-file-run-json-recording",
    "run",
    "{W}/ol.yaml",
    "--json",
    "{C}/ok/x",
    "--recording",
    "{C}/ok/x",
    expect="give two files",
)
case(
    "same-file-identify-out-json",
    "identify",
    "{W}/good.csv",
    "--out",
    "{C}/ok/x",
    "--json",
    "x",
    expect="give two files",
)
case(
    "same-file-identify-out-report",
    "identify",
    "{W}/good.csv",
    "--out",
    "{C}/ok/x.md",
    "--report",
    "{C}/ok/x.md",
    expect="give two files",
)
case(
    "same-file-diagnose-out-json",
    "diagnose",
    "{W}/good.csv",
    "--params",
    "{W}/params.yaml",
    "--out",
    "{C}/ok/x",
    "--json",
    "{C}/ok/x",
    expect="give two files",
)
case(
    "identify-out-is-data-relative",
    "identify",
    "../../../good.csv",
    "--out",
    "{W}/good.csv",
    expect="is one of the inputs",
)
case(
    "identify-out-is-validation-data",
    "identify",
    "{W}/good.csv",
    "--validate",
    "{W}/ol.yaml",
    "--out",
    "{W}/ol.yaml",
    expect="is one of the inputs",
)
case(
    "identify-out-is-describe",
    *("identify", "{W}/good.csv", "--describe", "{W}/desc.yaml", "--out", "{W}/desc.yaml"),
    expect="is one of the inputs",
)
case(
    "diagnose-out-is-params",
    *("diagnose", "{W}/good.csv", "--params", "{W}/params.yaml", "--out", "{W}/params.yaml"),
    expect="is one of the inputs",
)
case(
    "diagnose-json-is-holdout",
    *("diagnose", "{W}/good.csv", "--params", "{W}/params.yaml", "--holdout", "{W}/ol.yaml"),
    *("--json", "{W}/ol.yaml"),
    expect="is one of the inputs",
)
case(
    "campaign-json-is-params",
    *("campaign", "{W}/cl.yaml", "--params", "{W}/params.yaml", "--json", "{W}/params.yaml"),
    expect="is one of the inputs",
)
case(
    "generate-out-holds-params",
    *("generate", "--out", "{W}", "--params", "{W}/set1_a750_f0.5_y-3.csv"),
    expect="is one of the inputs",
)

# ---------------------------------------------------------------- option ranges
GENERATE_BAD = {
    "--amplitude": ("nan", "inf", "-inf", "-1"),
    "--freq": ("nan", "inf", "-inf", "0", "-1", "500", "1e9"),
    "--offset": ("nan", "inf", "-inf"),
    "--initial-angle": ("nan", "inf", "5", "-200"),
    "--gyro-noise": ("nan", "inf", "-1"),
    "--resolver-lsb": ("nan", "inf", "-0.1"),
    "--samples": ("0", "19", "-5", "100000000"),
    "--seed": ("-1",),
}
for option, values in GENERATE_BAD.items():
    for v in values:
        # OPTION=VALUE: argparse reads a separate "-inf" as an option.
        case(
            f"generate{option}={v}",
            "generate",
            "--set",
            "eq7",
            "--out",
            "{C}/ok/gen",
            f"{option}={v}",
        )
IDENTIFY_ARGS = ("identify", "{W}/good.csv", "--out", "{C}/ok/p.yaml")
DIAGNOSE_ARGS = ("diagnose", "{W}/good.csv", "--params", "{W}/params.yaml")
for option, v in [
    ("--rest-rate", "nan"),
    ("--rest-rate", "inf"),
    ("--rest-rate", "-1"),
    ("--population", "0"),
    ("--refine-evaluations", "0"),
    ("--min-regime-samples", "0"),
    ("--generations", "-1"),
    ("--seed", "-1"),
    ("--initial-angle", "nan"),
    ("--initial-angle", "-inf"),
]:
    case(f"identify{option}={v}", *IDENTIFY_ARGS, f"{option}={v}")
for option, v in [
    ("--max-rounds", "0"),
    ("--iterations", "0"),
    ("--initial-angle", "nan"),
    ("--initial-angle", "inf"),
    ("--candidates", "no_such_effect"),
]:
    case(f"diagnose{option}={v}", *DIAGNOSE_ARGS, f"{option}={v}")
case("run--seed=-1", "run", "{W}/ol.yaml", "--seed", "-1", "--no-recording")
case("campaign-n=0", "campaign", "{W}/cl.yaml", "-n", "0")
case("campaign--seed=-1", "campaign", "{W}/cl.yaml", "--seed", "-1")
case("campaign-open-loop-scenario", "campaign", "{W}/ol.yaml", "-n", "1")
case("report-n=0", "report", "-n", "0")
case("report--seed=-1", "report", "--seed", "-1")

# ---------------------------------------------------------------- refused combinations
case("run-engine-fast-closed-loop", "run", "{W}/cl.yaml", "--engine", "fast", "--no-recording")
case("run-spawn-no-recording", "run", "{W}/ol.yaml", "--spawn", "--no-recording")
case("run-connect-no-recording", "run", "{W}/ol.yaml", "--connect", "--no-recording")
case(
    "run-connect-url-no-recording",
    "run",
    "{W}/ol.yaml",
    "--connect",
    "rerun+http://127.0.0.1:1/proxy",
    "--no-recording",
)

# ---------------------------------------------------------------- scenarios
# (file name, YAML text); the open-loop text below is edited per case.
OPEN = (
    "name: tiny\nkind: open_loop\nduration_s: 0.05\n"
    "open_loop:\n  axis: inner_az\n"
    "  command: {amplitude_digits: 950.0, freq_hz: 0.5, offset_digits: 0.0}\n"
)
SCENARIO_EDITS = {
    "name-parent": ("name: tiny", "name: ../../x"),
    "name-absolute": ("name: tiny", "name: /tmp/isp_twin_x"),
    "name-slash": ("name: tiny", "name: a/b"),
    "name-backslash": ("name: tiny", "name: 'a\\\\b'"),
    "name-dotdot": ("name: tiny", "name: '..'"),
    "name-newline": ("name: tiny", 'name: "a\\nb/c"'),
    "unknown-key": ("duration_s", "duraton_s"),
    "duration-nan": ("duration_s: 0.05", "duration_s: .nan"),
    "duration-inf": ("duration_s: 0.05", "duration_s: .inf"),
    "duration-negative": ("duration_s: 0.05", "duration_s: -1"),
    "duration-text": ("duration_s: 0.05", "duration_s: long"),
    "duration-list": ("duration_s: 0.05", "duration_s: [1, 2]"),
    "kind-unknown": ("kind: open_loop", "kind: openloop"),
    "axis-unknown": ("axis: inner_az", "axis: inner_azz"),
    "freq-nyquist": ("freq_hz: 0.5", "freq_hz: 600"),
    "freq-zero": ("freq_hz: 0.5", "freq_hz: 0"),
    "amplitude-nan": ("amplitude_digits: 950.0", "amplitude_digits: .nan"),
    "amplitude-negative": ("amplitude_digits: 950.0", "amplitude_digits: -1"),
    "offset-inf": ("offset_digits: 0.0", "offset_digits: -.inf"),
    "top-level-list": ("name: tiny\n", "- name: tiny\n"),
    "yaml-syntax": ("command: {", "command: {{"),
    "tab-indent": ("  axis", "\taxis"),
    "seed-negative": ("name: tiny\n", "name: tiny\nseed: -3\n"),
    "seed-float": ("name: tiny\n", "name: tiny\nseed: 1.5\n"),
    "bool-for-number": ("duration_s: 0.05", "duration_s: true"),
    "parameters-missing": ("name: tiny\n", "name: tiny\nparameters: no_such_set\n"),
    "diverges-twin": ("amplitude_digits: 950.0", "amplitude_digits: 1.0e+30"),
}
for sid in SCENARIO_EDITS:
    case(f"scenario-{sid}", "run", f"{{W}}/scenario_{sid}.yaml", "--no-recording")
case(
    "scenario-diverges-fast",
    "run",
    "{W}/scenario_diverges-twin.yaml",
    "--engine",
    "fast",
    "--no-recording",
)
CLOSED_EDITS = {
    "no-moving-axis": ("amplitude_deg: 3.0", "amplitude_deg: 0.0"),
    "skip-after-end": ("skip_s: 0.01", "skip_s: 1.0"),
    "unknown-controller-axis": ("metrics:", "controller: {inner_azz: {}}\nmetrics:"),
    "gain-nan": ("metrics:", "controller: {inner_az: {pi: {kp_digit_per_count: .nan}}}\nmetrics:"),
    "follower-text": ("metrics:", "follower: yes please\nmetrics:"),
}
for sid in CLOSED_EDITS:
    for command in ("run", "campaign"):
        extra = ("--no-recording",) if command == "run" else ("-n", "1", "--jobs", "1")
        case(f"scenario-{sid}-{command}", command, f"{{W}}/closed_{sid}.yaml", *extra)

# ---------------------------------------------------------------- rig files
# Each case edits the shipped paper rig once; a closed-loop scenario names it.
RIG_EDITS = {
    "unknown-knob-key": ("    unit: Hz\n", "    unitt: Hz\n", "unitt: unknown key"),
    "value-out-of-range": ("    value: 70.0\n", "    value: 150.0\n", "gyro_scale.value"),
    "value-nan": ("    value: 70.0\n", "    value: .nan\n", "gyro_scale.value"),
    "value-text": ("    value: 200.0\n", "    value: fast\n", "gyro_bandwidth.value"),
    "unknown-cell": (
        "cells: [table4_1_6Hz_pi]\n",
        "cells: [table4_1_6Hz_pie]\n",
        "table4_1_6Hz_pie",
    ),
    "unknown-scenario-key": ("[gyro.bandwidth_hz]", "[gyro.bandwith_hz]", "bandwith_hz"),
    "provenance-unknown": ("provenance: assumption", "provenance: guess", "provenance"),
    "range-reversed": ("range: [100.0, 1000.0]", "range: [1000.0, 100.0]", "gyro_bandwidth.range"),
    "range-one-number": ("range: [100.0, 1000.0]", "range: 100.0", "gyro_bandwidth.range"),
    "key-set-twice": ("keys: [gyro.noise_deg_s]", "keys: [gyro.bandwidth_hz]", "also set by"),
    "missing-note": ("    note: Below one gyro count", "    nota: Below one gyro count", "nota"),
    "fit-on-assumption": (
        "    provenance: assumption\n    note: >-\n      First-order",
        "    provenance: assumption\n    fit: {cells: [table4_1_6Hz_pi], values: [200.0]}\n    note: >-\n      First-order",
        "only a calibrated knob",
    ),
    "fit-value-out-of-range": ("values: [50.0, 60.0,", "values: [5.0, 60.0,", "values[0]"),
    "calibrated-without-cells": (
        "    cells: [table4_0_5Hz_half_pi, table4_0_5Hz_pi, table5_pi, table5_pi_nfc]\n",
        "",
        "start_angle_held.cells",
    ),
    "when-unknown-key": (
        "when: {follower.enabled: false}",
        "when: {follower.enable: false}",
        "enable",
    ),
    "top-level-list": ("name: paper_rig\n", "- name: paper_rig\n", "rig"),
    "yaml-syntax": ("keys: [gyro.noise_deg_s]", "keys: [gyro.noise_deg_s", "not valid YAML"),
}
for rid in RIG_EDITS:
    for command in ("run", "campaign"):
        extra = ("--no-recording",) if command == "run" else ("-n", "1", "--jobs", "1")
        case(
            f"rig-{rid}-{command}",
            command,
            f"{{W}}/closed_rig_{rid}.yaml",
            *extra,
            expect=RIG_EDITS[rid][2],
        )
case("rig-missing", "run", "{W}/closed_rig_missing.yaml", "--no-recording", expect="rig")
for command in ("calibrate", "report"):
    case(
        f"rig-value-out-of-range-{command}",
        command,
        "--rig",
        "{W}/rig_value-out-of-range.yaml",
        "-n",
        "1",
        expect="gyro_scale.value",
    )
    case(f"rig-missing-{command}", command, "--rig", "no_such_rig", "-n", "1", expect="rig")
    case(f"runs-zero-{command}", command, "-n", "0", expect="--runs")
for bad in ("binary", "latin1", "nul", "directory", "unreadable"):
    case(
        f"rig-unreadable-{bad}",
        "run",
        f"{{W}}/closed_rig_bad_{bad}.yaml",
        "--no-recording",
        expect=INPUT_MESSAGES[bad],
    )

# ---------------------------------------------------------------- data files
DATA_FILES = {
    "nan-row": "t,u,omega,theta\n"
    + "".join(f"{k * 1e-3},1,2,3\n" for k in range(30))
    + "0.03,nan,2,3\n",
    "inf-cell": "t,u,omega,theta\n"
    + "".join(f"{k * 1e-3},1,{'inf' if k == 7 else 2},3\n" for k in range(30)),
    "missing-t": "time,u,omega,theta\n" + "".join(f"{k * 1e-3},1,2,3\n" for k in range(30)),
    "missing-u": "t,cmd,omega,theta\n" + "".join(f"{k * 1e-3},1,2,3\n" for k in range(30)),
    "no-rate-no-angle": "t,u\n" + "".join(f"{k * 1e-3},1\n" for k in range(30)),
    "text-cell": "t,u,omega,theta\n"
    + "".join(f"{k * 1e-3},{'x' if k == 4 else 1},2,3\n" for k in range(30)),
    "ragged-row": "t,u,omega,theta\n"
    + "".join(f"{k * 1e-3},1,2,3\n" for k in range(30))
    + "0.03,1,2\n",
    "time-backwards": "t,u,omega,theta\n"
    + "".join(f"{(29 - k) * 1e-3},1,2,3\n" for k in range(30)),
    "time-not-uniform": "t,u,omega,theta\n"
    + "".join(f"{(k + (k > 15)) * 1e-3},1,2,3\n" for k in range(30)),
    "too-few-samples": "t,u,omega,theta\n" + "".join(f"{k * 1e-3},1,2,3\n" for k in range(5)),
    "empty": "",
    "header-only": "t,u,omega,theta\n",
    "period-2ms": "t,u,omega,theta\n" + "".join(f"{k * 2e-3},1,2,3\n" for k in range(30)),
    "bom-then-bad-column": "\ufefftime,u,omega,theta\n"
    + "".join(f"{k * 1e-3},1,2,3\n" for k in range(30)),
}
for did in DATA_FILES:
    case(f"data-{did}-identify", "identify", f"{{W}}/data_{did}.csv", "--out", "{C}/ok/p.yaml")
    case(
        f"data-{did}-diagnose",
        "diagnose",
        f"{{W}}/data_{did}.csv",
        "--params",
        "{W}/params.yaml",
        "--out",
        "{C}/ok/d.yaml",
    )
MAPPINGS = {
    "map-unknown-key": ("--map", "tt=t"),
    "map-missing-column": ("--map", "t=time", "--map", "u=u", "--map", "omega=omega"),
    "map-bad-scale": ("--map", "t=t*fast", "--map", "u=u", "--map", "omega=omega"),
    "map-no-u": ("--map", "t=t", "--map", "omega=omega"),
    "describe-unknown-key": ("--describe", "{W}/desc_unknown_key.yaml"),
    "describe-not-mapping": ("--describe", "{W}/desc_list.yaml"),
    "describe-angle-text": ("--describe", "{W}/desc_angle_text.yaml"),
    "mat-without-mapping": (),
}
for mid, extra in MAPPINGS.items():
    data = "{W}/garbage.mat" if mid == "mat-without-mapping" else "{W}/good.csv"
    case(f"mapping-{mid}-identify", "identify", data, "--out", "{C}/ok/p.yaml", *extra)
    case(f"mapping-{mid}-diagnose", "diagnose", data, "--params", "{W}/params.yaml", *extra)
case(
    "mat-garbage-with-mapping",
    "identify",
    "{W}/garbage.mat",
    "--out",
    "{C}/ok/p.yaml",
    "--map",
    "t=data:0",
    "--map",
    "u=data:1",
    "--map",
    "omega=data:2",
)

# ---------------------------------------------------------------- parameter files
PARAMETER_EDITS = {
    "units-changed": ("units:", "units_old:"),
    "sample-time-negative": ("sample_time_s: 0.001", "sample_time_s: -0.001"),
    "sample-time-text": ("sample_time_s: 0.001", "sample_time_s: fast"),
}
for pid in PARAMETER_EDITS:
    case(f"parameters-{pid}-run", "run", "{W}/ol.yaml", "--params", f"{{W}}/params_{pid}.yaml")
    case(
        f"parameters-{pid}-identify",
        "identify",
        "{W}/good.csv",
        "--prior",
        f"{{W}}/params_{pid}.yaml",
        "--out",
        "{C}/ok/p.yaml",
    )

#: A valid ``fitted_with`` block (docs/identification.md) and the bad values
#: tried in it: each must name the file, the key and what is allowed.
FITTED_WITH = (
    "    fitted_with: {substeps: 10, midpoint_friction: true, split_reversals: true, "
    "exact_effect_hold: true, gyro_average: true, side_shift_steps: 0.5}\n"
)
FITTED_WITH_EDITS = {
    "substeps-zero": ("substeps: 10", "substeps: 0", "fitted_with.substeps"),
    "substeps-fraction": ("substeps: 10", "substeps: 2.5", "fitted_with.substeps"),
    "substeps-too-many": ("substeps: 10", "substeps: 1000", "fitted_with.substeps"),
    "substeps-text": ("substeps: 10", "substeps: ten", "fitted_with.substeps"),
    "flag-not-bool": ("gyro_average: true", "gyro_average: 1", "fitted_with.gyro_average"),
    "flag-text": ("midpoint_friction: true", "midpoint_friction: yes please", "midpoint"),
    "shift-negative": (
        "side_shift_steps: 0.5",
        "side_shift_steps: -0.25",
        "fitted_with.side_shift_steps",
    ),
    "shift-one": ("side_shift_steps: 0.5", "side_shift_steps: 1.0", "fitted_with.side_shift_steps"),
    "shift-nan": (
        "side_shift_steps: 0.5",
        "side_shift_steps: .nan",
        "fitted_with.side_shift_steps",
    ),
    "unknown-key": ("gyro_average: true", "gyro_averaging: true", "did you mean"),
    "missing-key": ("split_reversals: true, ", "", "fitted_with.split_reversals: missing"),
    "not-a-mapping": (FITTED_WITH, "    fitted_with: 10\n", "expected a mapping"),
}
for fid, (_, _, fragment) in FITTED_WITH_EDITS.items():
    case(
        f"fitted-with-{fid}-diagnose",
        "diagnose",
        "{W}/good.csv",
        "--params",
        f"{{W}}/params_fitted_{fid}.yaml",
        "--out",
        "{C}/ok/d.yaml",
        expect=f"params_fitted_{fid}.yaml: axes.inner_az.{fragment}"
        if fid not in ("flag-text", "unknown-key", "not-a-mapping")
        else fragment,
    )
    case(
        f"fitted-with-{fid}-identify-prior",
        "identify",
        "{W}/good.csv",
        "--prior",
        f"{{W}}/params_fitted_{fid}.yaml",
        "--out",
        "{C}/ok/p.yaml",
        expect=f"params_fitted_{fid}.yaml",
    )


def _build(root: Path) -> Path:
    world = build_world(root)
    for sid, (old, new) in SCENARIO_EDITS.items():
        assert old in OPEN, sid
        (world / f"scenario_{sid}.yaml").write_text(OPEN.replace(old, new, 1))
    from hostile_world import CLOSED_LOOP

    for sid, (old, new) in CLOSED_EDITS.items():
        assert old in CLOSED_LOOP, sid
        (world / f"closed_{sid}.yaml").write_text(CLOSED_LOOP.replace(old, new, 1))
    from isp_twin.resources import resource_root

    rig = (resource_root() / "models" / "rigs" / "paper_rig.yaml").read_text()
    for rid, (old, new, _) in RIG_EDITS.items():
        assert old in rig, rid
        (world / f"rig_{rid}.yaml").write_text(rig.replace(old, new, 1))
        (world / f"closed_rig_{rid}.yaml").write_text(f"{CLOSED_LOOP}rig: rig_{rid}.yaml\n")
    (world / "closed_rig_missing.yaml").write_text(f"{CLOSED_LOOP}rig: no_such_rig\n")
    for bad in ("binary", "latin1", "nul", "directory", "unreadable"):
        (world / f"closed_rig_bad_{bad}.yaml").write_text(f"{CLOSED_LOOP}rig: bad_{bad}.yaml\n")
    for did, text in DATA_FILES.items():
        (world / f"data_{did}.csv").write_text(text, encoding="utf-8")
    (world / "garbage.mat").write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    (world / "desc_unknown_key.yaml").write_text("columns: {t: t, u: u, omega: omega}\nunits: si\n")
    (world / "desc_list.yaml").write_text("- t\n- u\n")
    (world / "desc_angle_text.yaml").write_text(
        "columns: {t: t, u: u, omega: omega}\ninitial_angle_deg: north\n"
    )
    params = (world / "params.yaml").read_text()
    for pid, (old, new) in PARAMETER_EDITS.items():
        assert old in params, pid
        (world / f"params_{pid}.yaml").write_text(params.replace(old, new, 1))
    fitted = params.replace("  inner_az:\n", "  inner_az:\n" + FITTED_WITH, 1)
    assert fitted != params
    for fid, (old, new, _) in FITTED_WITH_EDITS.items():
        assert old in fitted, fid
        (world / f"params_fitted_{fid}.yaml").write_text(fitted.replace(old, new, 1))
    (world / "params_fitted_ok.yaml").write_text(fitted)
    write_csv(world / "set1_a750_f0.5_y-3.csv", good_table())
    for p in world.iterdir():
        if p.is_file() and not p.name.startswith("bad_unreadable"):
            p.chmod(0o666)  # writable by anyone: an input is refused as such, not as read-only
    world.chmod(0o777)
    return world


@pytest.fixture(scope="module")
def world():
    import_lazy_modules()
    root = Path(tempfile.mkdtemp(prefix="isp_twin_hostile_"))
    root.chmod(0o755)
    try:
        yield _build(root / "w")
    finally:
        release(root)
        shutil.rmtree(root)


def test_the_table_has_at_least_300_cases_with_unique_names():
    ids = [c.id for c in CASES]
    assert len(ids) == len(set(ids))
    assert len(ids) >= 300


@pytest.mark.parametrize("index", range(len(CASES)), ids=[c.id for c in CASES])
def test_hostile_input_exits_2_with_one_line_and_writes_nothing(world, index, capsys):
    c = CASES[index]
    folder = make_case_dir(world, index)
    argv = [a.replace("{W}", str(world)).replace("{C}", str(folder)) for a in c.argv]
    inputs_before = snapshot(world)
    before = snapshot(folder)
    with working_directory(folder / c.cwd), unprivileged():
        code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2, f"exit {code}; stderr: {err!r}; stdout: {out[-300:]!r}"
    assert "Traceback" not in err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert err.startswith(f"isp-twin {argv[0]}: error: "), err
    assert c.expect.lower() in err.lower(), err
    after = snapshot(folder)
    assert after == before, sorted(set(after) ^ set(before))
    world_after = {k: v for k, v in snapshot(world).items() if not k.startswith("cases")}
    world_before = {k: v for k, v in inputs_before.items() if not k.startswith("cases")}
    assert world_after == world_before
    assert not list(Path(world).rglob("*.part"))
    release(folder)
    shutil.rmtree(folder)


def test_unprivileged_really_drops_the_write_permission(world):
    """The permission cases above mean something only if `nobody` cannot write ro/."""
    folder = make_case_dir(world, 10_000)
    with unprivileged(), pytest.raises(PermissionError):
        (folder / "ro" / "x").write_text("x")
    with unprivileged(), pytest.raises(PermissionError):
        (world / "bad_unreadable.yaml").read_bytes()
    release(folder)
    shutil.rmtree(folder)


def test_data_files_in_the_table_are_otherwise_valid(world):
    """Each bad data file differs from a loadable one only by its defect."""
    from isp_twin.identification.measured import load_measured

    good = world / "ok_like.csv"
    good.write_text(DATA_FILES["nan-row"].replace("nan", "1"))
    assert len(load_measured(good)) == 31
    assert np.isfinite(load_measured(good).omega).all()
