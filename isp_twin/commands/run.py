"""`isp-twin run SCENARIO`: simulate a scenario, print its metrics, record it."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from isp_twin.errors import ScenarioError
from isp_twin.experiments.results import RunResult
from isp_twin.model.parameters import load_parameters
from isp_twin.output.files import check_outputs, is_stdout, transaction, write_text_atomic
from isp_twin.resources import find_scenario
from isp_twin.units import DEG
from isp_twin.vocabulary import SIDE_L, SIDE_R

__all__ = ["add_parser", "execute", "CLOSED_LOOP_UNITS", "OPEN_LOOP_UNITS"]

#: Units of the numbers in the JSON of a closed-loop run (metrics per axis).
CLOSED_LOOP_UNITS = {
    "isolation_percent": "% (Eq. 10)",
    "max_abs_error_deg_s": "deg/s",
    "rms_error_deg_s": "deg/s",
    "seed": "1",
}
#: Units of the numbers in the JSON of an open-loop run.
OPEN_LOOP_UNITS = {
    "peak_deg_s": "deg/s",
    "peak_positive_deg_s": "deg/s",
    "peak_negative_deg_s": "deg/s",
    "dead_zones_ms": "ms",
    "mean_dead_zone_ms": "ms",
}


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="simulate a scenario on the twin, print its metrics, write a Rerun recording",
        description=(
            "Simulate a scenario (a YAML file, or the bare name of a shipped scenario such as "
            "turbulence_1_6Hz) on the MuJoCo twin. Closed-loop scenarios print the isolation J "
            "(Eq. 10) per inner axis; open-loop scenarios print the Fig. 2 figures (peak rates "
            "and dead zones). Every run writes recordings/<scenario>.rrd."
        ),
    )
    p.add_argument("scenario", help="scenario file or shipped scenario name")
    p.add_argument("--seed", type=int, default=None, help="noise seed (default: the scenario's)")
    p.add_argument(
        "--params",
        type=Path,
        default=None,
        help="parameter file (default: the scenario's 'parameters')",
    )
    p.add_argument(
        "--json", type=Path, default=None, metavar="PATH", help="also write the metrics as JSON"
    )
    p.add_argument(
        "--recording",
        type=Path,
        default=None,
        metavar="PATH",
        help="recording path (default: recordings/<scenario>.rrd)",
    )
    p.add_argument("--no-recording", action="store_true", help="do not write a recording")
    p.add_argument("--spawn", action="store_true", help="also stream to a new Rerun viewer")
    p.add_argument(
        "--connect",
        nargs="?",
        const="",
        default=None,
        metavar="URL",
        help="also stream to a running Rerun viewer (default URL if none given)",
    )
    p.add_argument(
        "--engine",
        choices=("twin", "fast"),
        default="twin",
        help="open-loop only: MuJoCo twin (default) or the fast Eq. 6 model",
    )
    p.set_defaults(execute=execute)


def execute(args: argparse.Namespace) -> int:
    from isp_twin.experiments.scenario import load_scenario

    if args.no_recording and (args.spawn or args.connect is not None):
        flag = "--spawn" if args.spawn else "--connect"
        raise ScenarioError(f"{flag} streams the recording; it cannot go with --no-recording")
    scenario = load_scenario(find_scenario(args.scenario))
    if scenario.kind == "closed_loop" and args.engine == "fast":
        raise ScenarioError(
            f"{scenario.source}: --engine fast: the fast model is open-loop only; "
            "closed-loop scenarios run on the MuJoCo twin (drop --engine)"
        )
    params_path = args.params or scenario.parameters_path
    params = load_parameters(params_path)
    seed = scenario.seed if args.seed is None else args.seed
    if seed < 0:
        raise ScenarioError(f"--seed must be >= 0, got {seed}")
    name = scenario.name or Path(scenario.source or args.scenario).stem
    recording = None
    if not args.no_recording:
        from isp_twin.output.recording import default_recording_path

        recording = args.recording or default_recording_path(name)
    check_outputs(
        {"--json": args.json, "--recording": recording},
        inputs=[scenario.source, params_path],
    )
    _load_simulator(scenario, args.engine)
    print(f"scenario {name}  ({scenario.source})")
    print(f"parameters {params_path}  seed {seed}")
    if scenario.kind == "closed_loop":
        print(f"rig {scenario.rig}  ({scenario.rig_path})")

    if scenario.kind == "open_loop":
        result, payload = _run_open_loop(scenario, params, params_path, name, seed, args.engine)
    else:
        result, payload = _run_closed_loop(scenario, params, params_path, name, seed)
    # A run stopped by Ctrl-C still writes what it has, and says so.
    payload["interrupted"] = result.interrupted
    _write_outputs(args, result, payload, recording)
    if result.interrupted:
        print("interrupted: the outputs hold the run up to the interruption", file=sys.stderr)
        return 130
    return 0


def _load_simulator(scenario, engine: str) -> None:
    """Import the simulator (MuJoCo, numba) before the header: once the header is
    printed the run starts at once (and Ctrl-C from then on keeps what ran)."""
    if scenario.kind == "closed_loop":
        import isp_twin.experiments.closed_loop

        isp_twin.experiments.closed_loop.load_kernel()  # numba and the compiled loop, if available
    elif engine == "twin":
        import isp_twin.model.twin  # noqa: F401


def _write_outputs(args: argparse.Namespace, result, payload: dict, recording) -> None:
    """The JSON and the recording, as one transaction; then say where they went."""
    with transaction():
        if args.json is not None:
            write_text_atomic(args.json, json.dumps(payload, indent=2) + "\n")
        if recording is not None:
            from isp_twin.output.recording import record_run

            record_run(result, recording, spawn=args.spawn, connect=args.connect)
    if args.json is not None and not is_stdout(args.json):
        print(f"metrics written to {args.json}")
    if recording is not None:
        print(f"recording written to {recording}  (open it with: rerun {recording})")


def _run_closed_loop(scenario, params, params_path, name, seed):
    from isp_twin.experiments.closed_loop import run_scenario

    result = run_scenario(scenario, params=params, seed=seed, on_progress=_progress())
    metrics = dict(result.metrics)
    print()
    print(f"{'axis':<10} {'J [%]':>8} {'max|w1| [deg/s]':>16} {'rms w1 [deg/s]':>15}")
    for axis, m in metrics.items():
        if not isinstance(m, dict) or "isolation_percent" not in m:
            continue
        print(
            f"{axis:<10} {m['isolation_percent']:>8.2f} {m['max_abs_error_deg_s']:>16.4f} "
            f"{m['rms_error_deg_s']:>15.4f}"
        )
    payload = {
        "scenario": name,
        "parameters_file": str(params_path),
        "rig": result.rig,
        "nfc_parameters": result.nfc_parameters,
        "seed": seed,
        "metrics": metrics,
        "units": CLOSED_LOOP_UNITS,
    }
    return result, payload


def _run_open_loop(scenario, params, params_path, name, seed, engine):
    from isp_twin.experiments.open_loop import analyse_open_loop, simulate_open_loop

    ol = scenario.open_loop
    response = simulate_open_loop(
        params,
        axis=ol.axis,
        amplitude_digits=ol.command.amplitude_digits,
        freq_hz=ol.command.freq_hz,
        offset_digits=ol.command.offset_digits,
        duration_s=scenario.duration_s,
        initial_angle_rad=ol.initial_angle_deg * DEG,
        engine=engine,
    )
    skip = min(2.0 / ol.command.freq_hz, 0.5 * scenario.duration_s)
    figures = analyse_open_loop(response.t, response.omega, response.angle, skip_s=skip)
    _print_open_loop(figures, ol.axis, engine, skip)
    result = RunResult(
        scenario=name,
        scenario_text=scenario.text,
        parameters_file=str(params_path),
        parameters_text=Path(params_path).read_text(),
        seed=seed,
        t=response.t,
        signals={
            f"{ol.axis}/omega_relative": response.omega,
            f"{ol.axis}/command": response.u,
            f"{ol.axis}/angle": response.angle,
        },
        joint_angles={ol.axis: response.angle},
        metrics=_json_ready(figures.as_dict()),
        view_start_s=skip,
    )
    payload = {
        "scenario": name,
        "parameters_file": str(params_path),
        "seed": seed,
        "engine": engine,
        "open_loop": result.metrics,
        "units": OPEN_LOOP_UNITS,
    }
    return result, payload


def _print_open_loop(figures, axis: str, engine: str, skip: float) -> None:
    """The open-loop figures beside the paper's Fig. 2 values."""
    from isp_twin.experiments.open_loop import PAPER_FIG2

    print(f"\nopen loop, {axis}, engine {engine}: after {skip:g} s of start-up")
    print(f"{'regime':<8} {'peak [deg/s]':>13}")
    for regime, peak in figures.peak_deg_s.items():
        text = "not visited" if np.isnan(peak) else f"{peak:13.3f}"
        print(f"{regime:<8} {text:>13}")
    print(f"\n{'figure':<28} {'twin':>10} {'paper':>10}")
    rows = (
        ("peak positive [deg/s]", figures.peak_positive_deg_s, PAPER_FIG2["peak_positive_deg_s"]),
        ("peak negative [deg/s]", figures.peak_negative_deg_s, PAPER_FIG2["peak_negative_deg_s"]),
        (
            "dead zone, Y > 0 [ms]",
            figures.mean_dead_zone_ms(SIDE_R),
            PAPER_FIG2["dead_zone_right_ms"],
        ),
        (
            "dead zone, Y <= 0 [ms]",
            figures.mean_dead_zone_ms(SIDE_L),
            PAPER_FIG2["dead_zone_left_ms"],
        ),
    )
    for label, ours, paper in rows:
        text = "none" if np.isnan(ours) else f"{ours:10.2f}"
        print(f"{label:<28} {text:>10} {paper:>10.2f}")


def _json_ready(obj):
    """NaN -> None so the JSON is standard."""
    if isinstance(obj, dict):
        return {k: _json_ready(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_json_ready(v) for v in obj]
    if isinstance(obj, float) and np.isnan(obj):
        return None
    return obj


def _progress():
    """A progress callback for terminals, None otherwise."""
    if not sys.stderr.isatty():
        return None

    def report(t: float, duration: float) -> None:
        print(f"\r  t = {t:6.2f} / {duration:.2f} s", end="", file=sys.stderr, flush=True)
        if t >= duration:
            print(file=sys.stderr)

    return report
