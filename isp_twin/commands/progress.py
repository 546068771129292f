"""A sign of life for long commands (diagnose, campaign, report).

On a terminal one stderr line is rewritten every second with the elapsed
time; otherwise (a log file, CI) a plain line is printed every
`PLAIN_INTERVAL_S` seconds, so that a long silent stretch means a hang.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

__all__ = ["PLAIN_INTERVAL_S", "working"]

#: Seconds between two plain progress lines when stderr is not a terminal.
PLAIN_INTERVAL_S = 30.0


@contextmanager
def working(
    label: str, stream: TextIO | None = None, interval_s: float | None = None
) -> Iterator[None]:
    """Report `label` and the elapsed time on stderr while the block runs."""
    stream = stream or sys.stderr
    tty = stream.isatty()
    interval = interval_s if interval_s is not None else (1.0 if tty else PLAIN_INTERVAL_S)
    stop = threading.Event()
    start = time.monotonic()

    def tick() -> None:
        while not stop.wait(interval):
            elapsed = time.monotonic() - start
            text = f"{label}: {int(elapsed) // 60}:{int(elapsed) % 60:02d} elapsed"
            try:
                if tty:
                    print(f"\r  {text} ", end="", file=stream, flush=True)
                else:
                    print(text, file=stream, flush=True)
            except (OSError, ValueError):  # stream closed under us
                return

    thread = threading.Thread(target=tick, name="isp-twin-progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        if tty and time.monotonic() - start >= interval:
            print(file=stream, flush=True)
