"""Where the shipped model, parameter sets and scenarios are found.

In a checkout (or an editable install) they are the repository's top-level
`models/` and `scenarios/`; a regular install copies them under
`<prefix>/share/isp-twin/`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from isp_twin.errors import ResourceNotFound

__all__ = ["resource_root", "model_path", "default_parameters_path", "find_scenario"]


def resource_root() -> Path:
    """The folder holding `models/` and `scenarios/`."""
    repo = Path(__file__).resolve().parents[1]
    if (repo / "models" / "params").is_dir():
        return repo
    shared = Path(sys.prefix) / "share" / "isp-twin"
    if (shared / "models" / "params").is_dir():
        return shared
    raise ResourceNotFound("cannot find the isp-twin models folder (broken install?)")


def model_path() -> Path:
    """Path of the MJCF model `models/isp_4gimbal.xml`."""
    return resource_root() / "models" / "isp_4gimbal.xml"


def default_parameters_path() -> Path:
    """Path of the paper's Table 2 parameter set."""
    return resource_root() / "models" / "params" / "paper_table2.yaml"


def find_scenario(name: str | Path) -> Path:
    """Resolve a scenario given as a path or as a bare shipped name.

    `turbulence_1_6Hz`, `turbulence_1_6Hz.yaml` and `scenarios/turbulence_1_6Hz.yaml`
    all work, from any directory.
    """
    path = Path(name)
    if path.is_file():
        return path
    if path.is_dir():
        raise ResourceNotFound(f"{name}: is a directory, expected a scenario file")
    shipped = resource_root() / "scenarios"
    for candidate in (shipped / path.name, shipped / f"{path.name}.yaml"):
        if candidate.is_file():
            return candidate
    available = sorted(p.stem for p in shipped.glob("*.yaml"))
    raise ResourceNotFound(
        f"{name}: no such scenario file; shipped scenarios: {', '.join(available)}"
    )
