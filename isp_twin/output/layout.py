"""The default layout (Rerun blueprint) a recording opens with.

A run: tabs of few, large views: "isolation" (the 3D view beside each inner
axis's ω1 with J in the title), one tab per inner axis (rates, command and
NFC, friction, regime), "outer gimbals", "metadata". Residuals: the residual
over time and on the angle and rate timelines, beside their metadata.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import rerun.blueprint as rrb

from isp_twin.output.entities import OTHER, TIMELINE
from isp_twin.vocabulary import INNER_AXES

__all__ = ["INNER_AXES", "isolation_titles", "residual_blueprint", "run_blueprint"]

# The inner axes (the paper's isolated axes) get a column of views each.

_GROUP_TITLES = {
    "rates": "rates [deg/s]",
    "drive": "command and NFC [digits]",
    "friction": "friction torque [N·m]",
    "regime": "friction regime (0 R+, 1 R-, 2 L+, 3 L-)",
    "angle": "gimbal angle [deg]",
    OTHER: "other signals [SI]",
}
#: An inner axis's panels, in their order in its tab.
_AXIS_GROUPS = ("rates", "drive", "friction", "regime", "angle", OTHER)
#: Entity (below /<axis>/rates) of the inertial rate error ω1 that J measures.
_OMEGA1 = "omega_inertial_deg_s"
#: Where the 3D camera looks from and at [m] (world frame, z up): far enough to
#: hold the whole turntable (about 0.6 m wide, 0.8 m tall) while it rocks.
_EYE_POSITION = (1.9, -2.3, 1.5)
_EYE_TARGET = (0.0, 0.0, 0.3)

Groups = Mapping[str, Mapping[str, list[str]]]


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


def isolation_titles(metrics: Mapping[str, Any]) -> dict[str, str]:
    """axis -> title of its ω1 panel, with J of Eq. 10 when the metrics have it."""
    out = {}
    for axis in INNER_AXES:
        m = metrics.get(axis)
        if isinstance(m, Mapping) and "isolation_percent" in m:
            j = m["isolation_percent"]
            out[axis] = f"{axis}: isolation error ω1 [deg/s], J = {j:.2f} %"
    return out


def _scene_view() -> rrb.Spatial3DView:
    return rrb.Spatial3DView(
        origin="/scene",
        name="turntable and gimbals",
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=_EYE_POSITION,
            look_target=_EYE_TARGET,
            eye_up=(0.0, 0.0, 1.0),
        ),
    )


def _omega1_views(groups: Groups, isolation: Mapping[str, str], start_s: float) -> list[Any]:
    """Each inner axis's ω1 panel titled with its J (when the run has ω1 and J)."""
    return [
        _series_view(f"/{axis}/rates/{_OMEGA1}", title, start_s)
        for axis, title in isolation.items()
        if axis in groups and f"/{axis}/rates/{_OMEGA1}" in groups[axis].get("rates", [])
    ]


def _axis_tab(axis: str, groups: Mapping[str, list[str]], omega1_apart: bool, start_s: float):
    """An inner axis's panels in a grid (ω1 left out of its rates when it has its own)."""
    views = []
    for group in _AXIS_GROUPS:
        if group not in groups:
            continue
        contents = None
        if group == "rates" and omega1_apart:
            contents = ["$origin/**", f"- $origin/{_OMEGA1}"]
        views.append(
            _series_view(f"/{axis}/{group}", f"{axis} {_GROUP_TITLES[group]}", start_s, contents)
        )
    return rrb.Grid(*views, grid_columns=2 if len(views) > 2 else 1, name=axis)


def _outer_views(groups: Groups, start_s: float) -> list[Any]:
    """The follow errors together, then every other axis's groups one view each."""
    views: list[Any] = []
    follow = [f"/{a}/follow/**" for a in groups if "follow" in groups[a]]
    if follow:
        views.append(_series_view("/", "outer follow error [deg]", start_s, contents=follow))
    for axis, axis_groups in groups.items():
        if axis in INNER_AXES:
            continue
        for group in axis_groups:
            if group != "follow":
                views.append(
                    _series_view(f"/{axis}/{group}", f"{axis} {_GROUP_TITLES[group]}", start_s)
                )
    return views


def run_blueprint(
    groups: Groups,
    *,
    has_scene: bool,
    isolation: Mapping[str, str] | None = None,
    view_start_s: float = 0.0,
) -> rrb.Blueprint:
    """Tabs of few, large views: isolation (3D and each inner axis's ω1 with J),
    one tab per inner axis (its rates, drive, friction, regime), the outer
    gimbals, the metadata.

    Args:
        groups: axis -> group -> entity paths (`entities.signal_groups`).
        has_scene: the run has joint angles (a 3D view).
        isolation: axis -> title of its ω1 panel (`isolation_titles`).
        view_start_s: the series views start here [s] (after the start-up transient).
    """
    tabs: list[Any] = []
    first: list[Any] = [_scene_view()] if has_scene else []
    omega1 = _omega1_views(groups, isolation or {}, view_start_s)
    if omega1:
        first.append(rrb.Vertical(*omega1))
    if first:
        tabs.append(rrb.Horizontal(*first, name="isolation"))
    tabs += [
        _axis_tab(axis, groups[axis], bool(omega1), view_start_s)
        for axis in INNER_AXES
        if axis in groups
    ]
    last = _outer_views(groups, view_start_s)
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


def residual_blueprint(name: str) -> rrb.Blueprint:
    """The residual over time and against angle and rate, beside the metadata."""
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
