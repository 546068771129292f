"""Where a run's signals go in a recording: entity paths, panels and display units.

A signal ``"<axis>/<kind>"`` of a `RunResult` (SI) becomes the scalar series
``/<axis>/<group>/<kind>_<unit>`` in display units (deg/s, deg, amplifier
digits); a kind the table does not know is still recorded, unscaled (SI), in
the ``other`` group. The recorder writes these entities and the layout draws
them, so both read the one table here. Plain Python (no rerun).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from isp_twin.units import rad_to_deg

__all__ = [
    "OTHER",
    "RAD_TO_DEG",
    "SIGNAL_STYLES",
    "TIMELINE",
    "SignalStyle",
    "entity_path",
    "signal_groups",
    "signal_style",
    "split_name",
]

#: The recordings' timeline: a duration in seconds from the start of the run.
TIMELINE = "time"


@dataclass(frozen=True)
class SignalStyle:
    """How a signal is displayed: its panel, scale from SI, unit suffix and label."""

    group: str
    scale: float
    unit: str
    label: str


RAD_TO_DEG = float(rad_to_deg(1.0))
# Signal names of the closed-loop runner (see RunResult); unknown names are
# still recorded, unscaled, in the "other" panel.
SIGNAL_STYLES: dict[str, SignalStyle] = {
    "omega_carrier": SignalStyle("rates", RAD_TO_DEG, "deg_s", "ω carrier (turbulence)"),
    "omega_inertial": SignalStyle("rates", RAD_TO_DEG, "deg_s", "ω1 inertial"),
    "omega_relative": SignalStyle("rates", RAD_TO_DEG, "deg_s", "ω2 relative"),
    "gyro": SignalStyle("rates", RAD_TO_DEG, "deg_s", "gyro"),
    "command": SignalStyle("drive", 1.0, "digits", "u command"),
    "nfc": SignalStyle("drive", 1.0, "digits", "NFC feed-forward"),
    "friction": SignalStyle("friction", 1.0, "N_m", "friction torque"),
    "regime": SignalStyle("regime", 1.0, "index", "regime 0 R+, 1 R-, 2 L+, 3 L-"),
    "angle": SignalStyle("angle", RAD_TO_DEG, "deg", "gimbal angle"),
    "follow_error": SignalStyle("follow", RAD_TO_DEG, "deg", "follow error"),
}
#: The group (and axis) of what the table does not know.
OTHER = "other"


def split_name(name: str) -> tuple[str, str]:
    """``"inner_az/gyro"`` -> ``("inner_az", "gyro")``; no axis -> ``"other"``."""
    axis, _, kind = name.rpartition("/")
    return (axis or OTHER), kind


def signal_style(kind: str) -> SignalStyle:
    """The style of a signal kind; an unknown kind is shown unscaled under ``other``."""
    return SIGNAL_STYLES.get(kind, SignalStyle(OTHER, 1.0, "si", kind))


def entity_path(axis: str, kind: str) -> str:
    """``("inner_az", "gyro")`` -> ``/inner_az/rates/gyro_deg_s``."""
    style = signal_style(kind)
    return f"/{axis}/{style.group}/{kind}_{style.unit}"


def signal_groups(signals: Mapping[str, np.ndarray]) -> dict[str, dict[str, list[str]]]:
    """axis -> group -> entity paths, in the order of the signals."""
    groups: dict[str, dict[str, list[str]]] = {}
    for name in signals:
        axis, kind = split_name(name)
        groups.setdefault(axis, {}).setdefault(signal_style(kind).group, []).append(
            entity_path(axis, kind)
        )
    return groups
