"""The record of one simulated run, shared by the runner, metrics and recorder."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["RunResult"]


@dataclass(frozen=True)
class RunResult:
    """Time series and metadata of one run.

    Attributes:
        scenario: scenario name (file stem).
        scenario_text: the scenario file's text, as run.
        parameters_file: path of the parameter set used.
        parameters_text: that file's text.
        seed: noise seed.
        t: sample times [s], shape (N,).
        signals: name -> array of shape (N,); names are ``<axis>/<signal>``
            (e.g. ``inner_az/omega_inertial`` [rad/s]); SI units, see the
            producer's docstring for the list.
        joint_angles: joint name -> angle [rad], shape (N,), for the 3D view
            (turntable and gimbal joints).
        metrics: JSON-ready metrics (see `isp_twin.experiments.metrics`).
        interrupted: True when the run was stopped early (Ctrl-C); the series
            then end at the last completed sample.
        view_start_s: where the plots of a viewer start [s]: after the
            start-up transient (the metrics' skip), 0 to show everything.
        rig: the rig the scenario ran on (its `rig` key; '' when none applies).
        rig_text: the rig file's text.
        nfc_parameters: the parameter file the NFC compensated with ('plant':
            the plant's own set; '' when no NFC ran).
    """

    scenario: str
    scenario_text: str
    parameters_file: str
    parameters_text: str
    seed: int
    t: np.ndarray
    signals: Mapping[str, np.ndarray]
    joint_angles: Mapping[str, np.ndarray] = field(default_factory=dict)
    metrics: Mapping[str, Any] = field(default_factory=dict)
    interrupted: bool = False
    view_start_s: float = 0.0
    rig: str = ""
    rig_text: str = ""
    nfc_parameters: str = ""
