"""Isolation metrics of a closed-loop run (paper Eq. 10) and campaign statistics.

Definitions, per inner axis (inner_az, inner_el):

* omega (the carrier turbulence of Eq. 10): the inertial angular velocity of
  the turntable top (the ISP base), projected on that inner gimbal's joint
  axis at the current attitude, ``x_axis_of_joint . omega_table_top`` (the twin
  gives it as `carrier_rate`). For the 3-axis turntable this is what a gyro
  on the base aligned with the gimbal axis would read; with the gimbals near
  0 deg it is the yaw rate for inner_az and the pitch rate for inner_el, roll
  entering only through the small gimbal angles.
* omega_1: the true inertial rate of the inner gimbal about its joint axis
  (not the noisy gyro reading); the error is omega_1 - u_ref with u_ref = 0
  (for the tracking experiment, -omega_2 - omega = -omega_1: same magnitude).
* J = max|omega_1| / max|omega| * 100 %, over the steady-state window only:
  the first `skip_s` seconds are discarded (by default one period of the
  slowest turntable motion: the start from rest is not part of the paper's
  periodic experiment).
* max_abs_error_deg_s = max|omega_1|; rms_error_deg_s = sqrt(mean(omega_1^2))
  (the paper's "mean square value of error", quoted in deg/s).

An axis whose carrier rate stays below `MIN_CARRIER_RATE` (e.g. inner_el
when only the yaw moves) has no J (Eq. 10 is undefined): `run_metrics`
leaves it out, `axis_metrics` gives None.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from isp_twin.experiments.signals import signal_key
from isp_twin.units import DEG
from isp_twin.vocabulary import INNER_AXES

__all__ = [
    "MIN_CARRIER_RATE",
    "isolation_percent",
    "axis_metrics",
    "run_metrics",
    "CampaignStats",
    "campaign_stats",
    "format_metrics_table",
]

#: Below this peak carrier rate [rad/s] (0.01 deg/s) J is not defined.
MIN_CARRIER_RATE = 0.01 * DEG


def isolation_percent(omega1: np.ndarray, omega: np.ndarray) -> float:
    """Eq. 10: ``max|omega_1| / max|omega| * 100`` [%] (arrays of the same window)."""
    return float(np.max(np.abs(omega1)) / np.max(np.abs(omega)) * 100.0)


def axis_metrics(omega1: np.ndarray, omega: np.ndarray) -> dict[str, float | None]:
    """J, max |error| and RMS error of one axis over a window (rates in rad/s)."""
    omega1 = np.asarray(omega1, dtype=float)
    omega = np.asarray(omega, dtype=float)
    peak_carrier = float(np.max(np.abs(omega))) if omega.size else 0.0
    return {
        "isolation_percent": (
            isolation_percent(omega1, omega) if peak_carrier >= MIN_CARRIER_RATE else None
        ),
        "max_abs_error_deg_s": float(np.max(np.abs(omega1)) / DEG),
        "rms_error_deg_s": float(math.sqrt(np.mean(omega1**2)) / DEG),
    }


def run_metrics(
    t: np.ndarray,
    signals: Mapping[str, np.ndarray],
    skip_s: float,
    axes: Sequence[str] = INNER_AXES,
) -> dict[str, dict[str, float | None]]:
    """Metrics of every inner axis of a run, over ``t >= skip_s``.

    Args:
        t: sample times [s], shape (N,).
        signals: must hold ``<axis>/omega_inertial`` and ``<axis>/omega_carrier`` [rad/s].
        skip_s: start of the steady-state window [s].

    Returns:
        axis -> {isolation_percent, max_abs_error_deg_s, rms_error_deg_s},
        for the axes that see carrier motion; empty when the window holds no
        sample (a run interrupted early).
    """
    window = np.asarray(t) >= skip_s - 1e-12
    if not np.any(window):
        return {}
    out = {}
    for a in axes:
        w1 = signals[signal_key(a, "omega_inertial")][window]
        m = axis_metrics(w1, signals[signal_key(a, "omega_carrier")][window])
        if m["isolation_percent"] is not None:
            out[a] = m
    return out


@dataclass(frozen=True)
class CampaignStats:
    """Statistics of repeated runs, as Tables 5 and 6 give them.

    Attributes:
        runs: J of each run [%].
        average, best, worst: mean, min and max of J [%].
        range: worst - best [percentage points].
        variance: sample variance (ddof = 1) of J as a fraction, the paper's
            "square error" (Sect. 4.1: 1.0616E-4 for Table 5's PI runs).
    """

    runs: tuple[float, ...]
    average: float
    best: float
    worst: float
    range: float
    variance: float

    def as_dict(self) -> dict:
        return {
            "runs": list(self.runs),
            "average": self.average,
            "best": self.best,
            "worst": self.worst,
            "range": self.range,
            "variance": self.variance,
        }


def campaign_stats(j_percent: Sequence[float]) -> CampaignStats:
    """Average, best, worst, range and variance of the runs' J [%]."""
    x = np.asarray(j_percent, dtype=float)
    if x.size == 0:
        raise ValueError("campaign statistics need at least one run")
    variance = float(np.var(x / 100.0, ddof=1)) if x.size > 1 else 0.0
    return CampaignStats(
        runs=tuple(float(v) for v in x),
        average=float(x.mean()),
        best=float(x.min()),
        worst=float(x.max()),
        range=float(x.max() - x.min()),
        variance=variance,
    )


def format_metrics_table(metrics: Mapping[str, Mapping[str, float | None]]) -> str:
    """A plain-text table of `run_metrics` output."""
    lines = [f"{'axis':<10} {'J [%]':>8} {'max|err| [deg/s]':>17} {'rms err [deg/s]':>16}"]
    for axis, m in metrics.items():
        j = m["isolation_percent"]
        js = f"{j:8.2f}" if j is not None else f"{'n/a':>8}"
        lines.append(
            f"{axis:<10} {js} {m['max_abs_error_deg_s']:17.4f} {m['rms_error_deg_s']:16.4f}"
        )
    return "\n".join(lines)
