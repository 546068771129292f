"""Test helper: `benchmarks/identify_reference.py` loaded as a module, once
per process (`benchmarks/` is not a package; the script imports Dask)."""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path
from types import ModuleType

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "identify_reference.py"


@functools.cache
def reference_benchmark() -> ModuleType:
    spec = importlib.util.spec_from_file_location("identify_reference_bench", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
