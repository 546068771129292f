"""Shared fixtures."""

from __future__ import annotations

import os
import signal

import pytest

from isp_twin.model.parameters import load_parameters
from isp_twin.resources import default_parameters_path


def pytest_configure(config):
    """Each pytest-xdist worker runs numba's kernels on its share of the
    cores (at least one thread): with every worker on all of them, OpenMP's
    threads outnumber the cores and wait on each other (measured at stop 46:
    four end-to-end diagnose tests on 2 workers, 2 cores took 208 s wall and
    406 s CPU on all threads, 187 s and 346 s on one each). numba's kernels
    give the same numbers on any number of threads (tests/test_substep_model.py)."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers > 1:
        import numba

        numba.set_num_threads(max(1, numba.config.NUMBA_NUM_THREADS // workers))


@pytest.fixture(scope="session")
def paper_params():
    """The paper's Table 2 parameter set (models/params/paper_table2.yaml)."""
    return load_parameters(default_parameters_path())


def _default_ctrl_c() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture
def ctrl_c_delivered():
    """Ctrl-C raises KeyboardInterrupt in this process for the test, whatever
    the runner left: a shell that starts the suite in the background (``cmd
    &``, ``nohup``) hands it SIGINT ignored, and the Ctrl-C tests then saw no
    interrupt at all. Yields the same for a child process, as
    `subprocess.Popen`'s ``preexec_fn`` (SIGINT back to its default there, so
    that Python installs its handler)."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield _default_ctrl_c
    signal.signal(signal.SIGINT, before)
