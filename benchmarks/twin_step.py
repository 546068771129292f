"""Cost of one twin step against a bare ``mujoco.mj_step`` on the same model.

Prints the ratio (target <= 2.5). Both are timed as the minimum over repeats
of the mean time per step, on the same model and data: the twin's own model
(its frictionloss written by the twin), with the inner azimuth sliding under a
sine command and the turntable moving, so every branch of the friction logic runs.

    python benchmarks/twin_step.py
"""

from __future__ import annotations

import time

import isp_twin  # noqa: F401  # isort: skip  (first: its OpenBLAS settings precede numpy's)

import mujoco
import numpy as np

from isp_twin.model.parameters import load_parameters
from isp_twin.model.twin import Twin
from isp_twin.resources import default_parameters_path

STEPS = 4000
REPEATS = 7


def main() -> None:
    twin = Twin(load_parameters(default_parameters_path()))
    t = np.arange(STEPS) * twin.dt
    commands = np.zeros((STEPS, 4))
    commands[:, 0] = 950.0 * np.cos(2 * np.pi * 0.5 * t)  # Eq. 4, inner_az
    targets = np.zeros((STEPS, 3))
    targets[:, 0] = np.deg2rad(3.0) * np.sin(2 * np.pi * t / 6.0)  # 3 deg, 1/6 Hz

    def run_twin() -> float:
        twin.reset()
        start = time.perf_counter()
        for k in range(STEPS):
            twin.step(commands[k], targets[k])
        return (time.perf_counter() - start) / STEPS

    def run_bare() -> float:
        m, d = twin.model, twin.data
        twin.reset()
        start = time.perf_counter()
        for _ in range(STEPS):
            mujoco.mj_step(m, d)
        return (time.perf_counter() - start) / STEPS

    twin_s = min(run_twin() for _ in range(REPEATS))
    bare_s = min(run_bare() for _ in range(REPEATS))
    print(f"bare mj_step:  {bare_s * 1e6:7.2f} us/step")
    print(f"twin.step:     {twin_s * 1e6:7.2f} us/step")
    print(f"ratio:         {twin_s / bare_s:7.2f}  (target <= 2.5)")


if __name__ == "__main__":
    main()
