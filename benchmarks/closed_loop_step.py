"""Cost of one closed-loop step against a bare ``mujoco.mj_step`` of the same model.

Runs turbulence_1_6Hz (12 s, 12 001 samples) through `ClosedLoop` (physics,
friction, sensors, both rate loops, NFC, followers, the per-sample buffer; no
recording) and times a bare ``mj_step`` on the twin's own model and data
(with its noslip iterations) in the same process, alternating the two and
keeping the minimum of each over the repeats. Prints both and their ratio
(issue 9 targets: single-run <= 3.0, batched <= 2.0).

    python benchmarks/closed_loop_step.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import mujoco

from isp_twin.closed_loop import ClosedLoop
from isp_twin.scenario import load_scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scenario", default="turbulence_1_6Hz")
    args = ap.parse_args()
    loop = ClosedLoop(load_scenario(args.scenario))
    m, d = loop.twin.model, loop.twin.data
    steps = loop.n

    def closed_loop() -> float:
        loop.reset()
        start = time.perf_counter()
        loop.run()
        return (time.perf_counter() - start) / steps

    def bare() -> float:
        loop.reset()
        start = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(m, d)
        return (time.perf_counter() - start) / steps

    loop_s, bare_s = [], []
    for _ in range(args.repeats):
        bare_s.append(bare())
        loop_s.append(closed_loop())
    lo, bo = min(loop_s), min(bare_s)
    print(f"scenario {args.scenario}: {steps} steps, noslip_iterations {m.opt.noslip_iterations}")
    print(f"bare mj_step:       {bo * 1e6:7.2f} us/step")
    print(
        f"ClosedLoop.step:    {lo * 1e6:7.2f} us/step  (real-time factor {m.opt.timestep / lo:.0f})"
    )
    print(f"ratio:              {lo / bo:7.2f}  (targets: single run <= 3.0, batched <= 2.0)")


if __name__ == "__main__":
    main()
