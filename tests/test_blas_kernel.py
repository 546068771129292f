"""The OpenBLAS kernel is pinned on x86-64 machines with AVX2 (isp_twin/__init__.py):
the kernels round the fits' linear algebra differently and the least squares
then takes another path (reference clean seed 12, tests/test_restart_at_noise.py,
went from 2.0 to 1.12 noise sigmas held out on an AVX-512 kernel)."""

from __future__ import annotations

import os
import subprocess
import sys

from isp_twin import _avx2

PROBE = "import isp_twin, os; print(os.environ.get('OPENBLAS_CORETYPE', ''))"


def _kernel_seen(env_kernel: str | None) -> str:
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    if env_kernel is not None:
        env["OPENBLAS_CORETYPE"] = env_kernel
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_the_package_pins_the_haswell_kernel_where_the_cpu_has_avx2():
    assert _kernel_seen(None) == ("Haswell" if _avx2() else "")


def test_a_users_kernel_wins():
    assert _kernel_seen("Zen") == "Zen"
