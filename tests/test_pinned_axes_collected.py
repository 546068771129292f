"""The pinned axes (`benchmarks/pinned_axes`, end-to-end regressions run
apart from the suite for its time) stay runnable: pytest collects all of
them with the suite's helpers, so a renamed helper or stage fails here and
not first when someone runs them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: The tests moved out of the suite at stop 62 (docs/diagnosis.md "Stop 62: the pinned axes"),
#: clean 455 (stop 79) and cogging 464 (stop 81).
PINNED = 12


def test_every_pinned_axis_is_collected():
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "--collect-only",
            "-q",
            "-n",
            "0",
            "benchmarks/pinned_axes",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    # Quiet twice (the suite's options say -q too): one "file: count" line per file.
    counts = [line.rpartition(": ") for line in done.stdout.splitlines() if ": " in line]
    assert sum(int(n) for _, _, n in counts) == PINNED, done.stdout
