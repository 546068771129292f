"""The open-loop experiment of the paper's Fig. 2 (Eq. 4 input) and its analysis.

Drives one gimbal motor with ``offset + amplitude*cos(2*pi*f*t)`` digits, the
turntable at rest, and measures, per half-plane and direction, the peak rates
and the dead zones (intervals at rest around a reversal: from the first to the
last sample of zero rate, as the paper defines them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isp_twin.errors import SimulationDiverged
from isp_twin.model.axis_model import simulate
from isp_twin.model.effects import make_effect
from isp_twin.model.friction import side_of
from isp_twin.model.parameters import ParameterSet
from isp_twin.units import DEG
from isp_twin.vocabulary import DIRECTIONS, GIMBAL_AXES, SIDE_L, SIDE_R, SIDES

__all__ = [
    "PAPER_FIG2",
    "OpenLoopResponse",
    "OpenLoopFigures",
    "command_signal",
    "simulate_open_loop",
    "analyse_open_loop",
]

#: The paper's measured Fig. 2 figures (Sect. 2.1): peak rates [deg/s] and
#: dead-zone lengths [ms] for the Eq. 4 input.
PAPER_FIG2 = {
    "peak_positive_deg_s": 11.9783,
    "peak_negative_deg_s": -9.7475,
    "dead_zone_right_ms": 645.0,
    "dead_zone_left_ms": 210.0,
}

#: A rate below this counts as "at rest" [rad/s] (1e-3 deg/s, the stick
#: criterion of the twin's tests; the fast model produces exact zeros).
REST_RATE = 1e-3 * DEG
#: Rest intervals closer than this belong to one dead zone [s]: the paper
#: measures a dead zone from the first to the last zero of the rate around a
#: reversal, so short slips inside it (a bounce at a joint stop) do not split it.
MERGE_GAP_S = 0.05


@dataclass(frozen=True)
class OpenLoopResponse:
    """An open-loop run of one axis. Arrays (N,), SI; `u` in digits."""

    t: np.ndarray
    u: np.ndarray
    omega: np.ndarray
    angle: np.ndarray
    axis: str
    engine: str


@dataclass(frozen=True)
class OpenLoopFigures:
    """Fig. 2 figures of a run.

    Attributes:
        peak_deg_s: regime name (`REGIMES`) -> peak rate [deg/s] while in
            that regime; NaN where never visited.
        peak_positive_deg_s / peak_negative_deg_s: overall peaks [deg/s].
        dead_zones_ms: side name (`SIDES`: "R" angle > 0, "L" angle <= 0)
            -> lengths [ms] of each dead zone that starts on that side.
    """

    peak_deg_s: dict[str, float]
    peak_positive_deg_s: float
    peak_negative_deg_s: float
    dead_zones_ms: dict[str, list[float]]

    def mean_dead_zone_ms(self, side: int) -> float:
        """Mean dead zone [ms] on `side` (`SIDE_R` or `SIDE_L`); NaN if none."""
        zones = self.dead_zones_ms[SIDES[side]]
        return float(np.mean(zones)) if zones else float("nan")

    def as_dict(self) -> dict:
        return {
            "peak_deg_s": self.peak_deg_s,
            "peak_positive_deg_s": self.peak_positive_deg_s,
            "peak_negative_deg_s": self.peak_negative_deg_s,
            "dead_zones_ms": self.dead_zones_ms,
            "mean_dead_zone_ms": {SIDES[s]: self.mean_dead_zone_ms(s) for s in (SIDE_R, SIDE_L)},
            "paper": PAPER_FIG2,
        }


def command_signal(
    t: np.ndarray, amplitude_digits: float, freq_hz: float, offset_digits: float = 0.0
) -> np.ndarray:
    """Eq. 4 (offset 0) or Eq. 7 (offset -200): the open-loop command [digits]."""
    return offset_digits + amplitude_digits * np.cos(2 * np.pi * freq_hz * t)


def simulate_open_loop(
    params: ParameterSet,
    *,
    axis: str = "inner_az",
    amplitude_digits: float = 950.0,
    freq_hz: float = 0.5,
    offset_digits: float = 0.0,
    duration_s: float = 6.0,
    initial_angle_rad: float = 0.0,
    angle_limit_rad: float | None = 4.0 * DEG,
    engine: str = "twin",
) -> OpenLoopResponse:
    """Run the open-loop experiment on the MuJoCo twin or the fast model.

    Args:
        engine: "twin" (MuJoCo, the other gimbals commanded 0, base at rest)
            or "fast" (Eq. 6 with the same joint stop).
    """
    dt = params.sample_time_s
    n = int(round(duration_s / dt)) + 1
    t = np.arange(n) * dt
    u = command_signal(t, amplitude_digits, freq_hz, offset_digits)
    if engine == "fast":
        spec = params.axis(axis)
        r = simulate(
            spec.rate_params(),
            u,
            dt,
            angle0=initial_angle_rad,
            angle_limit=angle_limit_rad,
            effects=[make_effect(e, dt) for e in spec.effects],
        )
        _check_divergence(t, u, r.omega, axis)
        return OpenLoopResponse(t, u, r.omega, r.angle, axis, engine)

    from isp_twin.model.twin import Twin

    twin = Twin(params)
    twin.reset({axis: initial_angle_rad})
    i = GIMBAL_AXES.index(axis)
    omega = np.empty(n)
    angle = np.empty(n)
    command = np.zeros(len(GIMBAL_AXES))
    state = twin.state()
    omega[0], angle[0] = state.rate[i], state.angle[i]
    for k in range(1, n):
        command[i] = u[k - 1]
        twin.step(command)
        state = twin.state()
        omega[k], angle[k] = state.rate[i], state.angle[i]
    return OpenLoopResponse(t, u, omega, angle, axis, engine)


def _check_divergence(t: np.ndarray, u: np.ndarray, omega: np.ndarray, axis: str) -> None:
    """The MuJoCo twin's runaway limits, applied to a fast-model run.

    Raises:
        SimulationDiverged: a command or rate out of the twin's limits, or non-finite.
    """
    from isp_twin.model.twin import MAX_COMMAND, MAX_RATE

    for what, x, limit, unit in (
        ("command", u, MAX_COMMAND, "digits"),
        ("rate", omega, MAX_RATE, "rad/s"),
    ):
        bad = np.flatnonzero(~(np.abs(x) < limit))
        if bad.size:
            k = bad[0]
            raise SimulationDiverged(
                f"fast model diverged at t={t[k]:.4f} s: {axis} {what} = {x[k]} {unit} "
                f"(allowed |{what}| < {limit:g})"
            )


def _runs(mask: np.ndarray, merge_gap: int = 0) -> list[tuple[int, int]]:
    """(start, stop) index pairs of the True runs of `mask`; runs separated by
    at most `merge_gap` False samples are joined."""
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    runs = list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))
    merged: list[tuple[int, int]] = []
    for start, stop in runs:
        if merged and start - merged[-1][1] <= merge_gap:
            merged[-1] = (merged[-1][0], stop)
        else:
            merged.append((start, stop))
    return merged


def analyse_open_loop(
    t: np.ndarray, omega: np.ndarray, angle: np.ndarray, skip_s: float = 2.0
) -> OpenLoopFigures:
    """Peak rates per regime and dead zones per side, after `skip_s` of start-up.

    Dead zones touching either end of the analysed window are incomplete and
    not counted.
    """
    keep = t >= t[0] + skip_s
    t, omega, angle = t[keep], omega[keep], angle[keep]
    w_deg = omega / DEG
    right = angle > 0  # `side_of` on every sample
    peaks = {}
    # Regimes in `REGIMES` order; a sample at rest (sign 0) belongs to none.
    for side, on_side in ((SIDE_R, right), (SIDE_L, ~right)):
        for direction, sign in zip(DIRECTIONS, (1, -1)):
            sel = on_side & (np.sign(omega) == sign)
            peak = float(sign * np.max(sign * w_deg[sel])) if sel.any() else float("nan")
            peaks[SIDES[side] + direction] = peak
    dt = float(np.median(np.diff(t)))
    zones: dict[str, list[float]] = {name: [] for name in SIDES}
    for start, stop in _runs(np.abs(omega) <= REST_RATE, int(round(MERGE_GAP_S / dt))):
        if start == 0 or stop == len(t):
            continue
        # The paper's Fig. 2 split (Y <= 0 is L): no direction at a stop.
        zones[SIDES[side_of(angle[start], 0.0)]].append(float((stop - start) * dt * 1e3))
    return OpenLoopFigures(
        peak_deg_s=peaks,
        peak_positive_deg_s=float(w_deg.max()),
        peak_negative_deg_s=float(w_deg.min()),
        dead_zones_ms=zones,
    )
