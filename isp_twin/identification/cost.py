"""Eq. 9 on measured runs: the runs stacked as identify sees them
(`run_stack`) for the simulation error both commands share
(`isp_twin.estimation.simulation_error`), its residuals and RMS, and the
data's rate noise."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from isp_twin.estimation.coverage import (
    DeterminedPart,
    RegimeBreakaways,
    breakaway_counts,
    first_untrained_rest,
    rest_counts,
)
from isp_twin.estimation.simulation_error import RunStack, predict_one, stack_runs
from isp_twin.estimation.simulation_error import residuals as simulation_residuals
from isp_twin.estimation.verdict import SCALE_DIFFERENCE, noise_floor_of
from isp_twin.identification.measured import MeasuredData
from isp_twin.identification.read_out import Timing
from isp_twin.identification.side_angle import with_side_angle
from isp_twin.model.parameters import EffectSpec, RateParams
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, Integration
from isp_twin.units import DEG
from isp_twin.vocabulary import REGIMES

__all__ = [
    "run_stack",
    "simulate_data",
    "model_breakaways",
    "held_out_determined",
    "residuals",
    "rmse",
    "rate_noise",
]


def run_stack(
    data: Sequence[MeasuredData],
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
) -> RunStack:
    """The runs as Eq. 9 sees them, stacked for the shared simulation error
    (`isp_twin.estimation.simulation_error`): the half-plane from the
    `side_source` angle read at `timing`, every sample after the first
    counted, a first rate within `rest_rate_deg_s` [deg/s] or within three
    noise sigmas taken as rest (`stack_runs`)."""
    shift = timing.side_shift / integration.substeps
    runs = [with_side_angle(d, side_source, shift, integration.opens_on_boundary) for d in data]
    return stack_runs(
        runs,
        warmup=1,
        gyro_average=timing.gyro_average,
        integration=integration,
        rest=rest_rate_deg_s * DEG,
        side_follows_gyro=side_source == "measured",
    )


def simulate_data(
    rate: RateParams,
    d: MeasuredData,
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    effects: Sequence[EffectSpec] = (),
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
):
    """The model (Eq. 6 in `integration`'s sub-steps) driven by the run's
    command and measured angle; `AxisResponse`.

    `effects` (a parameter file's ``effects:``) are held fixed. With
    ``timing.gyro_average`` the returned rate is what a gyro averaging over
    each sample period reads (`Timing`).
    """
    stack = run_stack([d], side_source, rest_rate_deg_s, timing, integration)
    return predict_one(stack, rate.to_vector(), tuple(effects)).mapped(lambda a: a[0])


def model_breakaways(
    rate: RateParams,
    train: Sequence[MeasuredData],
    held_out: Sequence[MeasuredData],
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    effects: Sequence[EffectSpec] = (),
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
) -> tuple[np.ndarray, np.ndarray]:
    """Per regime (`REGIMES` order): how often the model driven by the
    `train` runs (`simulate_data`) breaks away from rest
    (`breakaway_counts`), and how many of its rests on the `held_out` runs
    push against the regime (`rest_counts`); on the axis's own rate where a
    sensor effect makes the reading differ."""

    def simulated(data):
        out = [
            simulate_data(rate, d, side_source, rest_rate_deg_s, effects, timing, integration)
            for d in data
        ]
        return [r.omega if r.omega_true is None else r.omega_true for r in out], [
            r.regime for r in out
        ]

    return breakaway_counts(*simulated(train)), rest_counts(*simulated(held_out))


def held_out_determined(
    rate: RateParams,
    held_out: Sequence[MeasuredData],
    untrained: Sequence[RegimeBreakaways],
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    effects: Sequence[EffectSpec] = (),
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
) -> tuple[DeterminedPart, ...]:
    """Per held-out run, the model's error before it first rests against one
    of the `untrained` regimes (`first_untrained_rest`, on the axis's own
    rate where a sensor effect makes the reading differ); () where none."""
    if not untrained:
        return ()
    wanted = [REGIMES.index(b.regime) for b in untrained]
    parts = []
    for d in held_out:
        r = simulate_data(rate, d, side_source, rest_rate_deg_s, effects, timing, integration)
        own = r.omega if r.omega_true is None else r.omega_true
        first = first_untrained_rest(own, r.regime, wanted)
        e = (np.asarray(r.omega) - np.asarray(d.omega))[1:first]
        rms = float(np.sqrt(np.mean(e**2))) if e.size else float("nan")
        parts.append(DeterminedPart(d.name, first, int(np.size(own)), rms))
    return tuple(parts)


def residuals(
    rate: RateParams,
    data: Sequence[MeasuredData] | RunStack,
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    effects: Sequence[EffectSpec] = (),
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
) -> np.ndarray:
    """Simulated minus measured rate [rad/s], sample 0 of each set left out.

    Shape (P, M) for batched params (M = total samples), else (M,). The
    shared simulation error (`isp_twin.estimation.simulation_error.residuals`)
    on `run_stack`'s stack; ``data`` may be that stack already (then the
    side source, rest level, timing and integration are the stack's).
    """
    single = np.ndim(rate.pole) == 1
    stack = (
        data
        if isinstance(data, RunStack)
        else run_stack(data, side_source, rest_rate_deg_s, timing, integration)
    )
    out = -simulation_residuals(stack, np.atleast_2d(rate.to_vector()), fixed=tuple(effects))
    return out[0] if single else out


def rmse(
    rate: RateParams,
    data: Sequence[MeasuredData],
    side_source: str = "measured",
    rest_rate_deg_s: float = 0.1,
    effects: Sequence[EffectSpec] = (),
    timing: Timing = Timing(),
    integration: Integration = DEFAULT_INTEGRATION,
) -> float | np.ndarray:
    """Eq. 9: RMS rate error over all sets at once [rad/s]."""
    e = residuals(rate, data, side_source, rest_rate_deg_s, effects, timing, integration)
    return np.sqrt(np.mean(e**2, axis=-1))


def rate_noise(data: Sequence[MeasuredData]) -> float:
    """White rate-noise scale of the measured runs [rad/s] for the fit's thresholds
    and weights (`noise_floor_of` at `SCALE_DIFFERENCE`; the verdict's floor is at
    `FLOOR_DIFFERENCE`)."""
    return noise_floor_of([d.omega for d in data], SCALE_DIFFERENCE)
