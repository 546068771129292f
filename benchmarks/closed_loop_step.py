"""Cost of one closed-loop step against a bare ``mujoco.mj_step`` of the same model.

Runs turbulence_1_6Hz (12 s, 12 001 samples) through `ClosedLoop` (physics,
friction, sensors, both rate loops, NFC, followers, the per-sample buffer; no
recording) and times a bare ``mj_step`` on the twin's own model and data
(with its noslip iterations) in the same process, alternating the two and
keeping the minimum of each over the repeats. Prints, each against the bare
step (issue 9 targets: single run <= 3.0, batched <= 2.0 per run):

* single run: `ClosedLoop.run` per sample (the compiled loop, and the Python
  blocks it replaces);
* batched: `--batch` runs of a sweep (seeds 1..B) through
  `isp_twin.experiments.sweep.execute.run_batch`, as one Dask task of ``isp-twin sweep
  --batch B`` runs them: wall time per sample including each run's set-up
  (scenario, twin, controllers) and its metrics.

    python benchmarks/closed_loop_step.py [--repeats 3] [--batch 8]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import isp_twin  # noqa: F401  # isort: skip  (first: its OpenBLAS settings precede numpy's)

import mujoco

from isp_twin.experiments.closed_loop import ClosedLoop
from isp_twin.experiments.scenario import load_scenario
from isp_twin.experiments.sweep.design import load_sweep
from isp_twin.experiments.sweep.execute import run_batch


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--scenario", default="turbulence_1_6Hz")
    args = ap.parse_args()
    loop = ClosedLoop(load_scenario(args.scenario))
    python_loop = ClosedLoop(load_scenario(args.scenario), compiled=False)
    m, d = loop.twin.model, loop.twin.data
    steps = loop.n
    with tempfile.TemporaryDirectory() as tmp:
        sweep_file = Path(tmp) / "seeds.yaml"
        sweep_file.write_text(
            f"scenario: {args.scenario}\nseeds: {{first: 1, count: {args.batch}}}\n"
        )
        specs = load_sweep(sweep_file).runs

    def closed_loop(which: ClosedLoop) -> float:
        which.reset()
        start = time.perf_counter()
        which.run()
        return (time.perf_counter() - start) / steps

    def bare() -> float:
        loop.reset()
        start = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(m, d)
        return (time.perf_counter() - start) / steps

    def batched() -> float:
        start = time.perf_counter()
        outcomes = run_batch(specs)
        elapsed = time.perf_counter() - start
        assert all(o.status == "ok" for o in outcomes), [o.error for o in outcomes]
        return elapsed / (steps * len(specs))

    closed_loop(loop)  # the kernel's first call loads (or compiles) it
    loop_s, python_s, batch_s, bare_s = [], [], [], []
    for _ in range(args.repeats):
        bare_s.append(bare())
        loop_s.append(closed_loop(loop))
        batch_s.append(batched())
        python_s.append(closed_loop(python_loop))
    lo, po, ba, bo = min(loop_s), min(python_s), min(batch_s), min(bare_s)
    print(f"scenario {args.scenario}: {steps} steps, noslip_iterations {m.opt.noslip_iterations}")
    print(f"bare mj_step:                 {bo * 1e6:7.2f} us/step")
    print(
        f"ClosedLoop.step (compiled):   {lo * 1e6:7.2f} us/step  ratio {lo / bo:5.2f}  "
        f"(real-time factor {m.opt.timestep / lo:.0f}; target single run <= 3.0)"
    )
    print(
        f"batched, {args.batch} runs per task:   {ba * 1e6:7.2f} us/step  ratio {ba / bo:5.2f}  "
        "(per run, set-up and metrics included; target <= 2.0)"
    )
    print(
        f"ClosedLoop.step (Python):     {po * 1e6:7.2f} us/step  ratio {po / bo:5.2f}  "
        "(the blocks the kernel reproduces)"
    )


if __name__ == "__main__":
    main()
