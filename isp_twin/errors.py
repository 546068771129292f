"""The package's exceptions.

Every error a user can cause derives from `IspTwinError`; the CLI turns them
into a one-line message and exit code 2. Each subclass also derives from the
builtin it refines, so callers can catch `ValueError` or `LookupError`.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

__all__ = [
    "IspTwinError",
    "ParameterError",
    "ScenarioError",
    "RigError",
    "DataError",
    "SimulationDiverged",
    "ResourceNotFound",
    "OutputError",
    "nearest",
]


class IspTwinError(Exception):
    """Base of all isp-twin errors."""


class ParameterError(IspTwinError, ValueError):
    """A parameter file or parameter value is invalid."""


class ScenarioError(IspTwinError, ValueError):
    """A scenario file is invalid (unknown key, bad value, bad type)."""


class RigError(IspTwinError, ValueError):
    """A rig file is invalid (unknown knob key, value outside its range, bad cell name...)."""


class DataError(IspTwinError, ValueError):
    """Measured data cannot be used (NaN, bad time base, missing column...)."""


class SimulationDiverged(IspTwinError, ArithmeticError):
    """A simulation produced non-finite or runaway values."""


class ResourceNotFound(IspTwinError, LookupError):
    """A file (scenario, model, parameter set, data) does not exist."""


class OutputError(IspTwinError, OSError):
    """An output cannot be written where asked (folder, permissions, an input...)."""


def nearest(name: str, choices: Iterable[str]) -> str:
    """A ' (did you mean X?)' hint, or '' when nothing is close."""
    match = difflib.get_close_matches(name, list(choices), n=1, cutoff=0.5)
    return f" (did you mean '{match[0]}'?)" if match else ""
