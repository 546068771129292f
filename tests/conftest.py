"""Shared fixtures."""

from __future__ import annotations

import pytest

from isp_twin.model.parameters import load_parameters
from isp_twin.resources import default_parameters_path


@pytest.fixture(scope="session")
def paper_params():
    """The paper's Table 2 parameter set (models/params/paper_table2.yaml)."""
    return load_parameters(default_parameters_path())
