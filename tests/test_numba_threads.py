"""numba's threads where several processes share the cores (stop 46).

With every process on all the cores, OpenMP's threads outnumber them and
wait on each other. The suite's workers (tests/conftest.py) and the
reference benchmark's commands run two at a time
(`benchmarks/identify_reference.py`, `command_threads`) each take their share.
"""

from __future__ import annotations

import os

import numba
import pytest
from reference_benchmark import reference_benchmark


@pytest.mark.parametrize(
    ("cores", "axes", "threads"), [(2, 1, 2), (2, 2, 1), (2, 3, 1), (8, 2, 4), (8, 3, 2), (1, 0, 1)]
)
def test_each_command_gets_the_cores_shared_by_the_axes_at_once(monkeypatch, cores, axes, threads):
    monkeypatch.setattr(os, "cpu_count", lambda: cores)
    assert reference_benchmark().command_threads(axes) == threads


def test_an_xdist_worker_runs_numba_on_its_share_of_the_cores():
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    share = (
        numba.config.NUMBA_NUM_THREADS
        if workers == 1
        else numba.config.NUMBA_NUM_THREADS // workers
    )
    assert numba.get_num_threads() == max(1, share)
