"""Reading a recording back: verify it, and read its series, documents and views.

For tests, reports and benchmarks: `verify_recording` runs ``rerun rrd
verify``; `read_series`, `read_text` and `read_views` read what the recorder
wrote (a series on the ``time`` timeline, a static text document, the default
layout's views).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from isp_twin.errors import DataError, ResourceNotFound
from isp_twin.output.entities import TIMELINE

__all__ = ["read_series", "read_text", "read_views", "rerun_executable", "verify_recording"]


def verify_recording(path: str | Path, *, timeout_s: float = 60.0) -> None:
    """Run ``rerun rrd verify`` on a file.

    Raises:
        ResourceNotFound: the file or the ``rerun`` executable is missing.
        DataError: the recording does not verify (message has the tool's output).
    """
    path = Path(path)
    if not path.is_file():
        raise ResourceNotFound(f"recording '{path}' does not exist")
    exe = rerun_executable()
    proc = subprocess.run(
        [exe, "rrd", "verify", str(path)],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        check=False,
    )
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["no output"]
        raise DataError(f"recording '{path}' fails 'rerun rrd verify': {tail[0]}")


def read_series(path: str | Path, entity: str, column: str = "Scalars:scalars"):
    """Read one time-indexed column of a recording back (for tests and reports).

    Args:
        path: an ``.rrd`` file written by this module.
        entity: entity path, e.g. ``/inner_az/rates/omega_inertial_deg_s``.
        column: the component column, ``"<Archetype>:<field>"``.

    Returns:
        ``(t, values)``: times on the ``time`` timeline [s], shape (M,), and the
        values, shape (M,) for scalars or (M, k) for vectors, sorted by time.

    Raises:
        ResourceNotFound: the file, or the entity's column, is not there.
    """
    times, values = [], []
    for batch in _batches(path, entity, static=False):
        if column in batch.schema.names and TIMELINE in batch.schema.names:
            ns = batch.column(TIMELINE).cast("int64").to_numpy(zero_copy_only=False)
            times.append(ns * 1e-9)
            rows = batch.column(column).to_pylist()
            values.append(np.array([np.squeeze(np.asarray(r, dtype=float)) for r in rows]))
    if not times:
        raise ResourceNotFound(f"recording '{path}' has no column {column} at {entity}")
    t = np.concatenate(times)
    order = np.argsort(t, kind="stable")
    return t[order], np.concatenate(values)[order]


def read_text(path: str | Path, entity: str) -> str:
    """The static text document logged at `entity` (e.g. ``/metadata/metrics``).

    Raises:
        ResourceNotFound: the file or the document is not there.
    """
    for batch in _batches(path, entity, static=True):
        if "TextDocument:text" in batch.schema.names:
            return batch.column("TextDocument:text").to_pylist()[0][0]
    raise ResourceNotFound(f"recording '{path}' has no text document at {entity}")


def read_views(path: str | Path) -> list[tuple[str, str, str]]:
    """The views of a recording's default layout: (name, origin, kind), e.g.
    ``("inner_az rates [deg/s]", "/inner_az/rates", "TimeSeries")``.

    Raises:
        ResourceNotFound: the file does not exist or holds no layout.
    """
    from rerun.chunk import RrdReader

    if not Path(path).is_file():
        raise ResourceNotFound(f"recording '{path}' does not exist")
    reader = RrdReader(path)
    if not reader.blueprints():
        raise ResourceNotFound(f"recording '{path}' holds no layout (blueprint)")
    views = []
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        if "ViewBlueprint:space_origin" in batch.schema.names:
            columns = ("display_name", "space_origin", "class_identifier")
            rows = zip(*(batch.column(f"ViewBlueprint:{c}").to_pylist() for c in columns))
            views += [(name[0], origin[0], kind[0]) for name, origin, kind in rows]
    return sorted(views)


def _batches(path: str | Path, entity: str, *, static: bool):
    from rerun.chunk import RrdReader

    if not Path(path).is_file():
        raise ResourceNotFound(f"recording '{path}' does not exist")
    for chunk in RrdReader(path).stream():
        if chunk.entity_path == entity and chunk.is_static == static:
            yield chunk.to_record_batch()


def rerun_executable() -> str:
    """The ``rerun`` CLI installed with the SDK (beside the interpreter), else on PATH."""
    name = "rerun.exe" if os.name == "nt" else "rerun"
    beside = Path(sys.executable).parent / name
    if beside.is_file():
        return str(beside)
    found = shutil.which("rerun")
    if found is None:
        raise ResourceNotFound(
            f"'rerun' executable not found beside {sys.executable} nor on PATH "
            "(install rerun-sdk==0.41.0)"
        )
    return found
