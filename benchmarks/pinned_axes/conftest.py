"""The pinned axes: end-to-end regression tests on the calibration axes of
past stops that the suite in `tests/` does not run.

Each test here replays, as a user runs them, `identify` and `diagnose` (or
the stage under test) on one reference axis that shaped a change, and
asserts what the change was made to do. They take one to two minutes each:
run together they made the suite some 15 minutes on 2 cores, over the
guide's ten. The suite keeps one such axis per case of issue 8 and the
cheap tests that pin each stage's wiring; these stay runnable as they are::

    python -m pytest benchmarks/pinned_axes

(7 minutes on 2 cores at stop 62; docs/diagnosis.md "Stop 62: the pinned axes"). Their
helpers are the suite's (`tests/` on the import path).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parents[2] / "tests"
if str(TESTS) not in sys.path:
    sys.path.insert(0, str(TESTS))

# The suite's modules whose checks the pinned tests call: their asserts
# explain a failure here as they do in the suite.
pytest.register_assert_rewrite(
    "identified_runs", "test_payload_side", "test_torque_effects_reference", "truth_error"
)
