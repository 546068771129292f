"""Atomic file output: a file is either written whole or not at all.

The older interface of `isp_twin.outputs`: inside ``outputs.transaction()``
the rename waits for the whole command's outputs.
"""

from __future__ import annotations

from pathlib import Path

from isp_twin.outputs import staged_path as atomic_path

__all__ = ["atomic_path", "write_text_atomic"]


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write `text` (UTF-8) to `path` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
