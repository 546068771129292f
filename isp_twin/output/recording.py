"""What a recording holds: a run (3D scene, signals, metadata) or a diagnosis's residuals.

`record_run` and `record_residuals` check their arrays, log them with
``send_columns`` (one call per series) and hand the stream to
`rerun_writer.write_recording`, which writes the file atomically and feeds a
viewer; the views come from `layout`.

Entity paths (timeline ``time``, a duration in seconds):

- ``/scene/table_yaw/table_pitch/.../inner_az``: the seven nested joints, each
  with a static box and a decimated ``Transform3D`` column; ``/scene/line_of_sight``
  is the camera boresight in the world frame.
- ``/<axis>/<group>/<signal>_<unit>``: one scalar series per signal, e.g.
  ``/inner_az/rates/omega_inertial_deg_s`` (`entities`).
- ``/metadata/{run,scenario,parameters,rig,metrics}``: static Markdown documents.
- ``/residuals/{time,scatter}/{before,after}_deg_s`` and ``/metadata/residuals``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

import isp_twin
from isp_twin.errors import DataError
from isp_twin.experiments.results import RunResult
from isp_twin.output.entities import (
    RAD_TO_DEG,
    TIMELINE,
    entity_path,
    signal_groups,
    signal_style,
    split_name,
)
from isp_twin.output.kinematics import BORESIGHT, JOINTS, joint_quaternions, line_of_sight
from isp_twin.output.layout import isolation_titles, residual_blueprint, run_blueprint
from isp_twin.output.rerun_writer import write_recording

__all__ = ["default_recording_path", "record_residuals", "record_run"]


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
#: The drawn boresight arrow's length [m].
_LOS_LENGTH = 0.8
_RESIDUAL_COLORS = {"before": (220, 80, 60), "after": (60, 160, 80)}


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
    groups = signal_groups(signals)
    blueprint = run_blueprint(
        groups,
        has_scene=bool(joints),
        isolation=isolation_titles(result.metrics),
        view_start_s=float(result.view_start_s),
    )

    def log(stream: rr.RecordingStream) -> None:
        _log_metadata_run(stream, result, len(t))
        _log_signals(stream, t, signals)
        if joints:
            _log_scene(stream, t, joints, decimate_3d)

    return write_recording(Path(path), log, blueprint, spawn=spawn, connect=connect)


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
    blueprint = residual_blueprint(name)

    def log(stream: rr.RecordingStream) -> None:
        before = arrays["before"] * RAD_TO_DEG
        after = arrays["after"] * RAD_TO_DEG
        _log_residual_metadata(stream, name, before, after, metadata)
        _log_residual_series(stream, t, {"before": before, "after": after}, arrays)

    return write_recording(Path(path), log, blueprint, spawn=spawn, connect=connect)


def _log_residual_metadata(
    stream: rr.RecordingStream,
    name: str,
    before: np.ndarray,
    after: np.ndarray,
    metadata: Mapping[str, Any] | None,
) -> None:
    """``/metadata/residuals``: the RMS before and after [deg/s] and the caller's facts."""
    facts = {
        "name": name,
        "samples": len(before),
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


def _log_residual_series(
    stream: rr.RecordingStream,
    t: np.ndarray,
    residuals_deg_s: Mapping[str, np.ndarray],
    arrays: Mapping[str, np.ndarray],
) -> None:
    """The residuals [deg/s] over time, and as points also on the angle and rate timelines."""
    index = [rr.TimeColumn(TIMELINE, duration=t)]
    # Scatter rows carry extra sequence timelines: choosing `angle_mdeg` or
    # `rate_mdeg_s` in the time panel plots the residual against angle or rate
    # (Rerun's 2D views are y-down, so a time series view is the honest plot).
    scatter_index = list(index)
    for key, timeline in (("angle", "angle_mdeg"), ("rate", "rate_mdeg_s")):
        if key in arrays:
            milli = np.round(arrays[key] * RAD_TO_DEG * 1000.0)
            scatter_index.append(
                rr.TimeColumn(timeline, sequence=np.nan_to_num(milli).astype(np.int64))
            )
    for key, values in residuals_deg_s.items():
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


def _log_signals(stream: rr.RecordingStream, t: np.ndarray, signals: Mapping[str, np.ndarray]):
    index = [rr.TimeColumn(TIMELINE, duration=t)]
    for name, values in signals.items():
        axis, kind = split_name(name)
        style = signal_style(kind)
        entity = entity_path(axis, kind)
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
    boresight = _LOS_LENGTH * BORESIGHT[None, :]
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
