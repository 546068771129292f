"""Shared fixtures."""

from __future__ import annotations

import signal

import pytest

from isp_twin.model.parameters import load_parameters
from isp_twin.resources import default_parameters_path


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
