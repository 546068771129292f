"""What a gyro sample means: the read-out timing of the data (`Timing`) and
the record of it a parameter file keeps (`fitted_with`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isp_twin.model.parameters import FittedWith
from isp_twin.model.substep_model import Integration

__all__ = [
    "TIMINGS",
    "Timing",
    "fitted_with",
    "recorded_model",
    "gyro_reading",
]


@dataclass(frozen=True)
class Timing:
    """What a sample of the data means in time, for the model's read-out.

    Attributes:
        side_shift: when in each step the half-plane is read [steps after
            the step's start; a step is a sample for Eq. 6, a sub-step for
            the sub-stepped model] (`side_angle`).
        gyro_average: the gyro reports the rate averaged over the sample
            period (most rate sensors integrate or filter), modelled as the
            mean of the model's rate at both ends of the step; else the rate
            at the sample instant (Eq. 6 as written).
    """

    side_shift: float = 0.0
    gyro_average: bool = False

    def describe(self) -> str:
        kind = "averaged over the sample" if self.gyro_average else "at the sample"
        return f"gyro rate {kind}, half-plane read at step start + {self.side_shift:g} step"


#: Read-out timings tried by `identify` (``side_source="measured"``); the paper's Eq. 6 first.
TIMINGS: tuple[Timing, ...] = tuple(
    Timing(shift, avg) for avg in (False, True) for shift in (0.0, 0.25, 0.5, 0.75)
)


def fitted_with(
    integration: Integration, timing: Timing, side_source: str = "measured"
) -> FittedWith:
    """The parameter file's record (`FittedWith`) of a fit's model, read-out
    timing and side source (the angle the half-plane was read from)."""
    return FittedWith(
        substeps=int(integration.substeps),
        midpoint_friction=bool(integration.midpoint_friction),
        split_reversals=bool(integration.split_reversals),
        exact_effect_hold=bool(integration.exact_effect_hold),
        gyro_average=bool(timing.gyro_average),
        side_shift_steps=float(timing.side_shift),
        midstep_angle=bool(integration.midstep_angle),
        rest_drive_gain=bool(integration.rest_drive_gain),
        split_sides=bool(integration.split_sides),
        side_source=side_source,
    )


def recorded_model(record: FittedWith) -> tuple[Integration, Timing]:
    """The model integration and read-out timing a `FittedWith` record names."""
    integration = Integration(
        record.substeps,
        record.midpoint_friction,
        record.split_reversals,
        record.exact_effect_hold,
        record.midstep_angle,
        record.rest_drive_gain,
        record.split_sides,
    )
    return integration, Timing(record.side_shift_steps, record.gyro_average)


def gyro_reading(omega: np.ndarray, average: bool) -> np.ndarray:
    """What the gyro reads of the model's rate, shape (..., N) along time.

    ``average``: the mean of the rate at both ends of each step (a gyro that
    averages over the sample period); else the rate itself.
    """
    if not average:
        return omega
    out = np.array(omega, dtype=float, copy=True)
    out[..., 1:] = 0.5 * (omega[..., 1:] + omega[..., :-1])
    return out
