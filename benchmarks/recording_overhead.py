"""Recording overhead: (run + record) / run, target at most 1.25 (issue 3).

Usage::

    python benchmarks/recording_overhead.py [--scenario turbulence_1_6Hz] [--synthetic-s 60]

Prints, from one measurement each:

1. the time to record a synthetic 60 s, 1 kHz closed-loop-like run (all
   inner/outer signals and the 7 joints), per simulated second;
2. if `isp_twin.experiments.closed_loop.run_scenario` exists, the scenario run without
   recording and the time to record its result, and the ratio.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import isp_twin  # noqa: F401  # isort: skip  (first: its OpenBLAS settings precede numpy's)

import numpy as np

from isp_twin.experiments.results import RunResult
from isp_twin.output.kinematics import JOINTS
from isp_twin.output.readback import verify_recording
from isp_twin.output.recording import record_run
from isp_twin.units import DEG

DT = 1e-3


def synthetic_run(duration_s: float) -> RunResult:
    """Sines on every signal the closed-loop runner writes, 1 kHz."""
    t = np.arange(round(duration_s / DT) + 1) * DT
    wave = np.sin(2 * np.pi * t / 6.0)
    signals = {}
    for axis in ("inner_az", "inner_el"):
        for name in ("omega_carrier", "omega_inertial", "omega_relative", "gyro"):
            signals[f"{axis}/{name}"] = DEG * wave
        for name in ("command", "friction", "nfc", "regime"):
            signals[f"{axis}/{name}"] = wave
    for axis in ("outer_az", "outer_el"):
        signals[f"{axis}/follow_error"] = 0.01 * DEG * wave
        signals[f"{axis}/command"] = wave
    joints = {name: 3 * DEG * wave for name, _ in JOINTS}
    return RunResult("synthetic", "", "", "", 0, t, signals, joints, {"J_db": -20.0})


def timed_record(result: RunResult, folder: Path) -> float:
    path = folder / f"{result.scenario}.rrd"
    start = time.perf_counter()
    record_run(result, path)
    elapsed = time.perf_counter() - start
    verify_recording(path)
    print(f"  {path.name}: {path.stat().st_size / 1e6:.1f} MB, rerun rrd verify: ok")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="turbulence_1_6Hz")
    parser.add_argument("--synthetic-s", type=float, default=60.0)
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        synthetic = synthetic_run(args.synthetic_s)
        rec_s = timed_record(synthetic, folder)
        print(
            f"synthetic {args.synthetic_s:.0f} s at 1 kHz ({len(synthetic.signals)} signals, "
            f"7 joints): record {rec_s:.3f} s = {1e3 * rec_s / args.synthetic_s:.2f} ms "
            "per simulated second"
        )

        try:
            from isp_twin.experiments.closed_loop import run_scenario
            from isp_twin.experiments.scenario import load_scenario
        except ImportError as exc:
            print(f"no closed-loop runner ({exc}); only the figure above is measured")
            return

        scenario = load_scenario(args.scenario)
        start = time.perf_counter()
        result = run_scenario(scenario)
        run_s = time.perf_counter() - start
        rec_s = timed_record(result, folder)
        sim_s = float(result.t[-1] - result.t[0])
        print(
            f"{args.scenario}: {sim_s:.1f} s simulated, run {run_s:.2f} s, "
            f"record {rec_s:.3f} s, (run + record) / run = {(run_s + rec_s) / run_s:.3f} "
            "(target <= 1.25)"
        )


if __name__ == "__main__":
    main()
