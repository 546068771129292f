"""numba's threads where the reference benchmark runs several axes at once
(stop 46): with every command on all the cores, OpenMP's threads outnumber
them and wait on each other; each command takes its share
(`benchmarks/identify_reference.py`, `command_threads`).

The suite's xdist workers keep numba's default (every core): capped to
their share, the suite ran 895-897 s in CI against 665-817 s before,
most likely because a long test then cannot use the core that a worker on
short tests leaves idle (not measured apart).
"""

from __future__ import annotations

import os

import pytest
from reference_benchmark import reference_benchmark


@pytest.mark.parametrize(
    ("cores", "axes", "threads"), [(2, 1, 2), (2, 2, 1), (2, 3, 1), (8, 2, 4), (8, 3, 2), (1, 0, 1)]
)
def test_each_command_gets_the_cores_shared_by_the_axes_at_once(monkeypatch, cores, axes, threads):
    monkeypatch.setattr(os, "cpu_count", lambda: cores)
    assert reference_benchmark().command_threads(axes) == threads
