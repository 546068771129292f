"""Rerun recordings of runs and residuals (the only module that imports rerun).

A recording is an ``.rrd`` file that opens in the Rerun viewer with a layout
built here: a 3D view of the turntable and the four gimbals, time series per
inner axis (rates in deg/s, command and NFC in amplifier digits, friction
torque, friction regime), the outer-gimbal follow errors and the run's
metadata (scenario text, parameter file, metrics, versions).

Files are written atomically: the stream is saved to a temporary file beside
the target *before* anything is logged, closed (which writes the footer), and
only then renamed onto the target. An interrupted or failed recording leaves
the target as it was and no temporary file behind.

Entity paths (timeline ``time``, a duration in seconds):

- ``/scene/table_yaw/table_pitch/.../inner_az``: the seven nested joints, each
  with a static box and a decimated ``Transform3D`` column; ``/scene/line_of_sight``
  is the camera boresight in the world frame.
- ``/<axis>/<group>/<signal>_<unit>``: one scalar series per signal, e.g.
  ``/inner_az/rates/omega_inertial_deg_s``.
- ``/metadata/{run,scenario,parameters,metrics}``: static Markdown documents.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

import isp_twin
from isp_twin.atomic import atomic_path
from isp_twin.errors import DataError, ResourceNotFound
from isp_twin.outputs import after_commit
from isp_twin.results import RunResult
from isp_twin.units import rad_to_deg
from isp_twin.vocabulary import INNER_AXES, JOINT_CHAIN

__all__ = [
    "JOINTS",
    "default_recording_path",
    "joint_quaternions",
    "line_of_sight",
    "read_series",
    "read_text",
    "read_views",
    "record_residuals",
    "record_run",
    "verify_recording",
]

APPLICATION_ID = "isp_twin"
TIMELINE = "time"
#: Default viewer URL for ``connect=""`` (Rerun's documented default).
DEFAULT_VIEWER_URL = "rerun+http://127.0.0.1:9876/proxy"
_SPAWN_PORT = 9876
#: How long to wait for a viewer to take the data before giving up [s].
_VIEWER_TIMEOUT_S = 10.0

# The inner axes (the paper's isolated axes) get a column of views each.

#: The seven joints of `JOINT_CHAIN` (outermost first, each nested in the
#: previous one), each with its rotation axis in the parent frame (the MJCF model's).
JOINTS: tuple[tuple[str, str], ...] = tuple(zip(JOINT_CHAIN, ("z", "y", "x", "z", "y", "y", "z")))
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class _Body:
    """Drawing of one joint's body: its offset in the parent frame and a box [m]."""

    offset: tuple[float, float, float]
    half_size: tuple[float, float, float]
    color: tuple[int, int, int]


# Schematic sizes only (not the MJCF model's): enough to see what moves.
_BODIES: dict[str, _Body] = {
    "table_yaw": _Body((0.0, 0.0, 0.0), (0.60, 0.60, 0.05), (110, 110, 120)),
    "table_pitch": _Body((0.0, 0.0, 0.45), (0.05, 0.55, 0.35), (140, 140, 150)),
    "table_roll": _Body((0.0, 0.0, 0.0), (0.45, 0.45, 0.03), (170, 170, 180)),
    "outer_az": _Body((0.0, 0.0, 0.10), (0.30, 0.30, 0.04), (60, 110, 200)),
    "outer_el": _Body((0.0, 0.0, 0.20), (0.04, 0.28, 0.15), (80, 140, 230)),
    "inner_el": _Body((0.0, 0.0, 0.0), (0.04, 0.18, 0.10), (230, 140, 60)),
    "inner_az": _Body((0.0, 0.0, 0.0), (0.12, 0.06, 0.06), (240, 180, 60)),
}
#: Camera boresight in the inner_az frame, and the drawn arrow length [m].
_BORESIGHT = np.array([1.0, 0.0, 0.0])
_LOS_LENGTH = 0.8


@dataclass(frozen=True)
class _SignalStyle:
    """How a signal is displayed: its panel, scale from SI, unit suffix and label."""

    group: str
    scale: float
    unit: str
    label: str


_RAD_TO_DEG = float(rad_to_deg(1.0))
# Signal names of the closed-loop runner (see RunResult); unknown names are
# still recorded, unscaled, in the "other" panel.
_SIGNALS: dict[str, _SignalStyle] = {
    "omega_carrier": _SignalStyle("rates", _RAD_TO_DEG, "deg_s", "ω carrier (turbulence)"),
    "omega_inertial": _SignalStyle("rates", _RAD_TO_DEG, "deg_s", "ω1 inertial"),
    "omega_relative": _SignalStyle("rates", _RAD_TO_DEG, "deg_s", "ω2 relative"),
    "gyro": _SignalStyle("rates", _RAD_TO_DEG, "deg_s", "gyro"),
    "command": _SignalStyle("drive", 1.0, "digits", "u command"),
    "nfc": _SignalStyle("drive", 1.0, "digits", "NFC feed-forward"),
    "friction": _SignalStyle("friction", 1.0, "N_m", "friction torque"),
    "regime": _SignalStyle("regime", 1.0, "index", "regime 0 R+, 1 R-, 2 L+, 3 L-"),
    "angle": _SignalStyle("angle", _RAD_TO_DEG, "deg", "gimbal angle"),
    "follow_error": _SignalStyle("follow", _RAD_TO_DEG, "deg", "follow error"),
}
_OTHER = "other"
_RESIDUAL_COLORS = {"before": (220, 80, 60), "after": (60, 160, 80)}
_GROUP_TITLES = {
    "rates": "rates [deg/s]",
    "drive": "command and NFC [digits]",
    "friction": "friction torque [N·m]",
    "regime": "friction regime (0 R+, 1 R-, 2 L+, 3 L-)",
    "angle": "gimbal angle [deg]",
    _OTHER: "other signals [SI]",
}


# --------------------------------------------------------------------------
# Kinematics (numpy only)


def joint_quaternions(angle: np.ndarray, axis: str) -> np.ndarray:
    """Rotations by `angle` about a frame axis, as quaternions.

    Args:
        angle: joint angles [rad], shape (N,).
        axis: ``"x"``, ``"y"`` or ``"z"``.

    Returns:
        Quaternions in Rerun's (x, y, z, w) order, shape (N, 4).
    """
    angle = np.asarray(angle, dtype=float)
    q = np.zeros(angle.shape + (4,))
    q[..., _AXIS_INDEX[axis]] = np.sin(0.5 * angle)
    q[..., 3] = np.cos(0.5 * angle)
    return q


def _rotation_matrices(angle: np.ndarray, axis: str) -> np.ndarray:
    """Rotation matrices about a frame axis, shape (N, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    i = _AXIS_INDEX[axis]
    j, k = (i + 1) % 3, (i + 2) % 3
    r = np.zeros(np.shape(angle) + (3, 3))
    r[..., i, i] = 1.0
    r[..., j, j] = c
    r[..., k, k] = c
    r[..., k, j] = s
    r[..., j, k] = -s
    return r


def line_of_sight(joint_angles: Mapping[str, np.ndarray], n: int) -> np.ndarray:
    """The camera boresight (inner_az frame +x) in the world frame.

    Args:
        joint_angles: joint name -> angle [rad], shape (n,); missing joints are 0.
        n: number of samples.

    Returns:
        Unit vectors, shape (n, 3).
    """
    rot = np.broadcast_to(np.eye(3), (n, 3, 3))
    for name, axis in JOINTS:
        if name in joint_angles:
            rot = rot @ _rotation_matrices(np.asarray(joint_angles[name], dtype=float), axis)
    return rot @ _BORESIGHT


# --------------------------------------------------------------------------
# Public API


def default_recording_path(scenario: str, folder: str | Path = "recordings") -> Path:
    """``recordings/<scenario>.rrd`` (relative to the working directory)."""
    return Path(folder) / f"{scenario}.rrd"


def record_run(
    result: RunResult,
    path: str | Path,
    *,
    spawn: bool = False,
    connect: str | None = None,
    decimate_3d: int = 20,
) -> Path:
    """Write a run to an ``.rrd`` file, and optionally stream it to a viewer.

    Args:
        result: the run.
        path: target file; written atomically (previous file kept on failure).
        spawn: also start a Rerun viewer and stream to it.
        connect: also stream to the viewer at this URL (``""`` = default URL).
        decimate_3d: keep every n-th sample for the 3D view.

    Returns:
        `path`.

    Raises:
        DataError: a signal or joint angle does not match ``result.t`` in length.
    """
    t = np.asarray(result.t, dtype=float)
    if t.ndim != 1:
        raise DataError(f"RunResult '{result.scenario}': t must be 1-D, got shape {t.shape}")
    owner = f"RunResult '{result.scenario}'"
    signals = _check_series("signal", result.signals, t, owner)
    joints = _check_series("joint angle", result.joint_angles, t, owner)
    if decimate_3d < 1:
        raise DataError(f"decimate_3d must be >= 1, got {decimate_3d}")
    groups = _signal_groups(signals)
    blueprint = _run_blueprint(
        groups,
        has_scene=bool(joints),
        isolation=_isolation_titles(result.metrics),
        view_start_s=float(result.view_start_s),
    )

    def log(stream: rr.RecordingStream) -> None:
        _log_metadata_run(stream, result, len(t))
        _log_signals(stream, t, signals)
        if joints:
            _log_scene(stream, t, joints, decimate_3d)

    return _write(Path(path), log, blueprint, spawn=spawn, connect=connect)


def record_residuals(
    name: str,
    t: np.ndarray,
    residual_before: np.ndarray,
    residual_after: np.ndarray,
    path: str | Path,
    *,
    angle: np.ndarray | None = None,
    rate: np.ndarray | None = None,
    metadata: Mapping[str, Any] | None = None,
    spawn: bool = False,
    connect: str | None = None,
) -> Path:
    """Write rate residuals before and after a model correction to an ``.rrd`` file.

    Shows the two residuals over time and, when given, against the gimbal
    angle and rate (where position- or rate-dependent effects stand out).

    Args:
        name: what the residuals belong to (e.g. ``"inner_az"``), shown as title.
        t: sample times [s], shape (N,).
        residual_before: measured minus model rate before the correction [rad/s], (N,).
        residual_after: the same after the correction [rad/s], (N,).
        path: target file; written atomically.
        angle: gimbal angle [rad], (N,), optional.
        rate: gimbal rate [rad/s], (N,), optional.
        metadata: JSON-ready facts shown as text (effect found, its parameters...).
        spawn: also start a Rerun viewer and stream to it.
        connect: also stream to the viewer at this URL (``""`` = default URL).

    Returns:
        `path`.

    Raises:
        DataError: an array does not match `t` in length.
    """
    t = np.asarray(t, dtype=float)
    series = {"before": residual_before, "after": residual_after}
    if angle is not None:
        series["angle"] = angle
    if rate is not None:
        series["rate"] = rate
    if t.ndim != 1:
        raise DataError(f"residuals '{name}': t must be 1-D, got shape {t.shape}")
    arrays = _check_series("array", series, t, f"residuals '{name}'")
    blueprint = _residual_blueprint(name)

    def log(stream: rr.RecordingStream) -> None:
        before = arrays["before"] * _RAD_TO_DEG
        after = arrays["after"] * _RAD_TO_DEG
        facts = {
            "name": name,
            "samples": len(t),
            "rms_before_deg_s": _rms(before),
            "rms_after_deg_s": _rms(after),
            "isp_twin": isp_twin.__version__,
            "rerun_sdk": rr.__version__,
        }
        text = f"# Residuals: {name}\n\n" + _markdown_table(facts)
        if metadata:
            text += "\n## Metadata\n\n" + _markdown_table(_flatten(metadata))
            text += "\n```json\n" + json.dumps(metadata, indent=2, default=str) + "\n```\n"
        _log_text(stream, "/metadata/residuals", text)
        index = [rr.TimeColumn(TIMELINE, duration=t)]
        # Scatter rows carry extra sequence timelines: choosing `angle_mdeg` or
        # `rate_mdeg_s` in the time panel plots the residual against angle or rate
        # (Rerun's 2D views are y-down, so a time series view is the honest plot).
        scatter_index = list(index)
        for key, timeline in (("angle", "angle_mdeg"), ("rate", "rate_mdeg_s")):
            if key in arrays:
                milli = np.round(arrays[key] * _RAD_TO_DEG * 1000.0)
                scatter_index.append(
                    rr.TimeColumn(timeline, sequence=np.nan_to_num(milli).astype(np.int64))
                )
        for key, values in (("before", before), ("after", after)):
            color = _RESIDUAL_COLORS[key]
            entity = f"/residuals/time/{key}_deg_s"
            stream.log(entity, rr.SeriesLines(names=key, colors=[color]), static=True)
            stream.send_columns(entity, indexes=index, columns=rr.Scalars.columns(scalars=values))
            entity = f"/residuals/scatter/{key}_deg_s"
            stream.log(
                entity,
                rr.SeriesPoints(names=key, colors=[color], marker_sizes=[1.5]),
                static=True,
            )
            stream.send_columns(
                entity, indexes=scatter_index, columns=rr.Scalars.columns(scalars=values)
            )

    return _write(Path(path), log, blueprint, spawn=spawn, connect=connect)


def verify_recording(path: str | Path, *, timeout_s: float = 60.0) -> None:
    """Run ``rerun rrd verify`` on a file.

    Raises:
        ResourceNotFound: the file or the ``rerun`` executable is missing.
        DataError: the recording does not verify (message has the tool's output).
    """
    path = Path(path)
    if not path.is_file():
        raise ResourceNotFound(f"recording '{path}' does not exist")
    exe = _rerun_executable()
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


# --------------------------------------------------------------------------
# Writing


def _write(path: Path, log, blueprint: rrb.Blueprint, *, spawn: bool, connect: str | None) -> Path:
    """Save to a temporary file beside `path`, log, close, rename; then feed a viewer.

    The file and the viewer get separate streams with the same recording id, so
    an unreachable viewer can neither block nor spoil the file.
    """
    recording_id = str(uuid.uuid4())
    # A Ctrl-C here would cost the whole recording of a finished run: the
    # file (a fraction of a second) is completed first, then the interrupt raised.
    with _sigint_deferred(), atomic_path(path) as tmp:
        stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
        try:
            # Saved before anything is logged, so the file holds everything.
            stream.save(tmp, default_blueprint=blueprint)
            log(stream)
            stream.flush()
        finally:
            # Closing writes the footer; also on error, before atomic_path removes tmp.
            stream.disconnect()
        _make_readable(tmp)
    if spawn or connect is not None:
        # After the file is in place (the whole command's outputs, inside a
        # transaction): a viewer that fails then cannot cost the file.
        after_commit(
            lambda: _send_to_viewer(
                path, log, blueprint, recording_id, spawn=spawn, connect=connect
            )
        )
    return path


@contextmanager
def _sigint_deferred() -> Iterator[None]:
    """Hold SIGINT until the block ends, then raise KeyboardInterrupt.

    Only in the main thread with Python's default handler installed;
    elsewhere the block runs unchanged.
    """
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return
    received: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if received:
        raise KeyboardInterrupt


def _send_to_viewer(
    path: Path,
    log,
    blueprint: rrb.Blueprint,
    recording_id: str,
    *,
    spawn: bool,
    connect: str | None,
) -> None:
    url = connect or DEFAULT_VIEWER_URL
    if not spawn:
        _check_reachable(url, path)
    stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    try:
        if spawn:
            stream.spawn(port=_SPAWN_PORT, default_blueprint=blueprint)
        else:
            stream.connect_grpc(url, default_blueprint=blueprint)
        log(stream)
        stream.flush(timeout_sec=_VIEWER_TIMEOUT_S)
    except (RuntimeError, OSError) as exc:
        where = "a spawned viewer" if spawn else f"the viewer at {url}"
        raise ResourceNotFound(
            f"could not stream to {where} ({str(exc).splitlines()[0]}); "
            f"the recording was saved to '{path}'"
        ) from None
    finally:
        stream.disconnect()


def _check_reachable(url: str, path: Path) -> None:
    """Fail fast when nothing listens at the viewer URL.

    Rerun's client otherwise retries for several seconds before giving up.
    """
    try:
        parts = urlsplit(url)
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if host is None or port is None:
        return
    try:
        socket.create_connection((host, port), timeout=_VIEWER_TIMEOUT_S).close()
    except OSError as exc:
        raise ResourceNotFound(
            f"no Rerun viewer at {url} ({exc.strerror or exc}); "
            f"start one with 'rerun', or omit --connect; the recording was saved to '{path}'"
        ) from None


def _make_readable(path: Path) -> None:
    """Give the file the usual permissions (the temporary file is created 0600)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


def _rerun_executable() -> str:
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


def _check_series(
    kind: str, series: Mapping[str, Any], t: np.ndarray, owner: str
) -> dict[str, np.ndarray]:
    out = {}
    for key, values in series.items():
        arr = np.asarray(values, dtype=float)
        if arr.shape != t.shape:
            raise DataError(
                f"{owner}: {kind} '{key}' has shape {arr.shape}, expected {t.shape} like t"
            )
        out[key] = arr
    return out


# --------------------------------------------------------------------------
# Logging


def _split_name(name: str) -> tuple[str, str]:
    """``"inner_az/gyro"`` -> ``("inner_az", "gyro")``; no axis -> ``"other"``."""
    axis, _, kind = name.rpartition("/")
    return (axis or _OTHER), kind


def _style(kind: str) -> _SignalStyle:
    return _SIGNALS.get(kind, _SignalStyle(_OTHER, 1.0, "si", kind))


def _entity(axis: str, kind: str) -> str:
    style = _style(kind)
    return f"/{axis}/{style.group}/{kind}_{style.unit}"


def _signal_groups(signals: Mapping[str, np.ndarray]) -> dict[str, dict[str, list[str]]]:
    """axis -> group -> entity paths, in the order of the signals."""
    groups: dict[str, dict[str, list[str]]] = {}
    for name in signals:
        axis, kind = _split_name(name)
        groups.setdefault(axis, {}).setdefault(_style(kind).group, []).append(_entity(axis, kind))
    return groups


def _log_signals(stream: rr.RecordingStream, t: np.ndarray, signals: Mapping[str, np.ndarray]):
    index = [rr.TimeColumn(TIMELINE, duration=t)]
    for name, values in signals.items():
        axis, kind = _split_name(name)
        style = _style(kind)
        entity = _entity(axis, kind)
        label = f"{axis} {style.label}"
        if style.group == "regime":
            # Integer regime: hold each value until the next sample.
            lines = rr.SeriesLines(names=label, interpolation_mode="StepAfter")
        else:
            lines = rr.SeriesLines(names=label)
        stream.log(entity, lines, static=True)
        stream.send_columns(
            entity, indexes=index, columns=rr.Scalars.columns(scalars=values * style.scale)
        )


def _log_scene(
    stream: rr.RecordingStream, t: np.ndarray, joints: Mapping[str, np.ndarray], decimate: int
) -> None:
    stream.log("/scene", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    keep = slice(None, None, decimate)
    td = t[keep]
    index = [rr.TimeColumn(TIMELINE, duration=td)]
    n = len(td)
    entity = "/scene"
    for name, axis in JOINTS:
        entity = f"{entity}/{name}"
        body = _BODIES[name]
        stream.log(
            entity,
            rr.Boxes3D(half_sizes=[body.half_size], colors=[body.color], fill_mode="Solid"),
            static=True,
        )
        angle = joints.get(name)
        angle = np.zeros(n) if angle is None else angle[keep]
        # translation and rotation in the same row: updating one alone resets the other.
        translation = np.broadcast_to(np.asarray(body.offset, dtype=float), (n, 3))
        stream.send_columns(
            entity,
            indexes=index,
            columns=rr.Transform3D.columns(
                translation=translation, quaternion=joint_quaternions(angle, axis)
            ),
        )
    boresight = _LOS_LENGTH * _BORESIGHT[None, :]
    stream.log(
        f"{entity}/boresight",
        rr.Arrows3D(vectors=boresight, colors=[(240, 60, 60)]),
        static=True,
    )
    los = line_of_sight({k: v[keep] for k, v in joints.items()}, n)
    stream.log("/scene/line_of_sight", rr.Arrows3D.from_fields(colors=[(60, 200, 60)]), static=True)
    stream.send_columns(
        "/scene/line_of_sight",
        indexes=index,
        columns=rr.Arrows3D.columns(vectors=_LOS_LENGTH * los, origins=np.zeros((n, 3))),
    )


def _log_text(stream: rr.RecordingStream, entity: str, markdown: str) -> None:
    stream.log(entity, rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN), static=True)


def _log_metadata_run(stream: rr.RecordingStream, result: RunResult, n: int) -> None:
    t = np.asarray(result.t, dtype=float)
    run = {
        "scenario": result.scenario,
        "seed": result.seed,
        "samples": n,
        "duration_s": float(t[-1] - t[0]) if n else 0.0,
        "interrupted": result.interrupted,
        "parameters_file": result.parameters_file,
        "rig": result.rig,
        "nfc_parameters": result.nfc_parameters,
        "isp_twin": isp_twin.__version__,
        "rerun_sdk": rr.__version__,
    }
    title = f"# Run: {result.scenario}" + (" (interrupted)" if result.interrupted else "")
    _log_text(stream, "/metadata/run", title + "\n\n" + _markdown_table(run))
    _log_text(
        stream,
        "/metadata/scenario",
        f"# Scenario `{result.scenario}`\n\n```yaml\n{result.scenario_text}\n```\n",
    )
    _log_text(
        stream,
        "/metadata/parameters",
        f"# Parameters `{result.parameters_file}`\n\n```yaml\n{result.parameters_text}\n```\n",
    )
    if result.rig_text:
        _log_text(
            stream,
            "/metadata/rig",
            f"# Rig `{result.rig}`\n\n```yaml\n{result.rig_text}\n```\n",
        )
    metrics = dict(result.metrics)
    text = "# Metrics\n\n"
    if metrics:
        text += _markdown_table(_flatten(metrics))
        text += "\n```json\n" + json.dumps(metrics, indent=2, default=str) + "\n```\n"
    else:
        text += "(none)\n"
    _log_text(stream, "/metadata/metrics", text)


def _rms(x: np.ndarray) -> float:
    finite = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(finite**2))) if finite.size else float("nan")


def _flatten(data: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(_flatten(value, name + "/"))
        else:
            flat[name] = value
    return flat


def _markdown_table(rows: Mapping[str, Any]) -> str:
    def cell(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.6g}"
        return str(v).replace("|", "\\|").replace("\n", " ")

    lines = ["| key | value |", "|---|---|"]
    lines += [f"| {k} | {cell(v)} |" for k, v in rows.items()]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------
# Layout


def _series_view(
    origin: str, name: str, start_s: float = 0.0, contents: Sequence[str] | None = None
) -> rrb.TimeSeriesView:
    """A time-series view; data before `start_s` (the start-up transient) is not
    drawn, so the y axis scales to the part worth looking at."""
    time_ranges = None
    if start_s > 0:
        time_ranges = rrb.VisibleTimeRange(
            TIMELINE,
            start=rrb.TimeRangeBoundary.absolute(seconds=start_s),
            end=rrb.TimeRangeBoundary.infinite(),
        )
    return rrb.TimeSeriesView(
        origin=origin,
        contents=list(contents) if contents is not None else "$origin/**",
        name=name,
        time_ranges=time_ranges,
        plot_legend=rrb.PlotLegend(corner="LeftTop"),
    )


def _metadata_tabs(names: Sequence[str]) -> rrb.Tabs:
    return rrb.Tabs(
        *(rrb.TextDocumentView(origin=f"/metadata/{n}", name=n) for n in names),
        name="metadata",
    )


#: Entity (below /<axis>/rates) of the inertial rate error ω1 that J measures.
_OMEGA1 = "omega_inertial_deg_s"
#: Where the 3D camera looks from and at [m] (world frame, z up): far enough to
#: hold the whole turntable (about 0.6 m wide, 0.8 m tall) while it rocks.
_EYE_POSITION = (1.9, -2.3, 1.5)
_EYE_TARGET = (0.0, 0.0, 0.3)


def _isolation_titles(metrics: Mapping[str, Any]) -> dict[str, str]:
    """axis -> title of its ω1 panel, with J of Eq. 10 when the metrics have it."""
    out = {}
    for axis in INNER_AXES:
        m = metrics.get(axis)
        if isinstance(m, Mapping) and "isolation_percent" in m:
            j = m["isolation_percent"]
            out[axis] = f"{axis}: isolation error ω1 [deg/s], J = {j:.2f} %"
    return out


def _run_blueprint(
    groups: Mapping[str, Mapping[str, list[str]]],
    *,
    has_scene: bool,
    isolation: Mapping[str, str] | None = None,
    view_start_s: float = 0.0,
):
    """Tabs of few, large views: isolation (3D and each inner axis's ω1 with J),
    one tab per inner axis (its rates, drive, friction, regime), the outer
    gimbals, the metadata."""
    isolation = isolation or {}
    tabs: list[Any] = []
    first: list[Any] = []
    if has_scene:
        first.append(
            rrb.Spatial3DView(
                origin="/scene",
                name="turntable and gimbals",
                eye_controls=rrb.EyeControls3D(
                    kind=rrb.Eye3DKind.Orbital,
                    position=_EYE_POSITION,
                    look_target=_EYE_TARGET,
                    eye_up=(0.0, 0.0, 1.0),
                ),
            )
        )
    omega1 = [
        _series_view(f"/{axis}/rates/{_OMEGA1}", title, view_start_s)
        for axis, title in isolation.items()
        if axis in groups and f"/{axis}/rates/{_OMEGA1}" in groups[axis].get("rates", [])
    ]
    if omega1:
        first.append(rrb.Vertical(*omega1))
    if first:
        tabs.append(rrb.Horizontal(*first, name="isolation"))

    for axis in INNER_AXES:
        if axis not in groups:
            continue
        views = []
        for group in ("rates", "drive", "friction", "regime", "angle", _OTHER):
            if group not in groups[axis]:
                continue
            contents = None
            if group == "rates" and omega1:  # ω1 has its own panel
                contents = ["$origin/**", f"- $origin/{_OMEGA1}"]
            views.append(
                _series_view(
                    f"/{axis}/{group}", f"{axis} {_GROUP_TITLES[group]}", view_start_s, contents
                )
            )
        tabs.append(rrb.Grid(*views, grid_columns=2 if len(views) > 2 else 1, name=axis))

    last: list[Any] = []
    follow = [f"/{a}/follow/**" for a in groups if "follow" in groups[a]]
    if follow:
        last.append(_series_view("/", "outer follow error [deg]", view_start_s, contents=follow))
    for axis, axis_groups in groups.items():
        if axis in INNER_AXES:
            continue
        for group in axis_groups:
            if group != "follow":
                last.append(
                    _series_view(f"/{axis}/{group}", f"{axis} {_GROUP_TITLES[group]}", view_start_s)
                )
    if last:
        tabs.append(rrb.Vertical(*last, name="outer gimbals"))
    tabs.append(_metadata_tabs(("run", "scenario", "parameters", "metrics")))
    # The side panels and the time panel start collapsed (room for the plots);
    # the play bar stays.
    return rrb.Blueprint(
        rrb.Tabs(*tabs, active_tab=0),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline=TIMELINE, state="collapsed"),
    )


def _residual_blueprint(name: str) -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.TimeSeriesView(origin="/residuals/time", name=f"{name} residual [deg/s]"),
                rrb.TimeSeriesView(
                    origin="/residuals/scatter",
                    name=f"{name} residual [deg/s] (timeline: time, angle_mdeg, rate_mdeg_s)",
                ),
                name="residuals",
            ),
            rrb.TextDocumentView(origin="/metadata/residuals", name="metadata"),
            column_shares=[3, 1],
        ),
        rrb.TimePanel(timeline=TIMELINE),
    )
