"""The OpenBLAS kernel is pinned on x86-64 machines with AVX2 (isp_twin/__init__.py):
the kernels round the fits' linear algebra differently and the least squares
then takes another path (reference clean seed 12, tests/test_restart_at_noise.py,
went from 2.0 to 1.12 noise sigmas held out on an AVX-512 kernel)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

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


BLAS_VARS = ("OPENBLAS_NUM_THREADS", "OPENBLAS_CORETYPE")
ROOT = Path(__file__).resolve().parents[1]


def _warned(code: str, env_set: dict[str, str]) -> bool:
    """Whether `code` run in a fresh interpreter warns that the BLAS settings
    came too late, the two OpenBLAS variables only as `env_set` gives them."""
    env = {k: v for k, v in os.environ.items() if k not in BLAS_VARS} | env_set
    cmd = [sys.executable, "-W", "error::RuntimeWarning", "-c", code]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0 or "RuntimeWarning" in out.stderr, out.stderr
    return "numpy was imported before isp_twin" in out.stderr


def test_numpy_loaded_first_is_said_not_silent():
    # The settings can no longer act: a script's fits would take the
    # machine's own kernel and threads (docs/diagnosis.md "Stop 70").
    assert _warned("import numpy, isp_twin", {})


def test_the_package_loaded_first_or_the_settings_given_is_silent():
    assert not _warned("import isp_twin, numpy", {})
    given = {"OPENBLAS_NUM_THREADS": "1", "OPENBLAS_CORETYPE": "Haswell"}
    assert not _warned("import numpy, isp_twin", given)


@pytest.mark.parametrize("script", sorted(p.name for p in (ROOT / "benchmarks").glob("*.py")))
def test_every_benchmark_loads_the_package_before_numpy(script):
    # Run as a script, benchmarks/ first on sys.path; `run_name` keeps its main() from running.
    code = (
        f"import runpy, sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); "
        f"runpy.run_path({str(ROOT / 'benchmarks' / script)!r}, run_name='imported')"
    )
    assert not _warned(code, {})
