"""The effect interface: what an effect may hook into, and its parameter check.

Every effect module subclasses `Effect`; the package (`isp_twin.model.effects`)
collects them into the registry `EFFECTS`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from isp_twin.errors import ParameterError, nearest

__all__ = ["Effect", "elementwise_run", "true_rates"]


class Effect:
    """Base class: no effect. Subclasses set `name`, `param_names` and override hooks."""

    name: ClassVar[str] = "none"
    param_names: ClassVar[tuple[str, ...]] = ()
    #: False where `acceleration` depends on the angle alone (no rate, no
    #: state) and is elementwise, its parameters broadcasting along the last
    #: axis: the sub-stepped model then evaluates it over the whole run in
    #: one call, before the kernel (`isp_twin.model.substep_model`).
    acceleration_uses_rate: ClassVar[bool] = True
    #: True where the sub-stepped model (m > 1) integrates the effect's state
    #: inside its sub-steps, with the friction and the stick test, from
    #: `substep_columns` (LuGre's bristles); it then calls none of the hooks
    #: below (the twin, Eq. 6 and m = 1, `isp_twin.model.axis_model`, still do).
    in_substeps: ClassVar[bool] = False
    #: Parameters a parameter set may leave out, with the value they then
    #: take (a parameter added to an effect after files were written with it:
    #: `resonance`'s ``payload_fraction``).
    defaults: ClassVar[dict[str, float]] = {}
    #: Parameters that act only inside the sub-steps (m > 1): Eq. 6 and m = 1
    #: do not see them, so the diagnosis holds them at their start there
    #: (`isp_twin.diagnosis.candidates`).
    substep_only: ClassVar[tuple[str, ...]] = ()
    #: True where a finite-difference slope of the model needs the model's
    #: own sub-steps, not the least squares' coarser ones
    #: (`isp_twin.estimation.simulation_error.JACOBIAN_SUBSTEPS`): a state
    #: integrated in the sub-steps (a payload mode, LuGre's bristles), or an
    #: action resolved to one sub-step (a fractional input delay). With 4
    #: sub-steps for 10, the truth of a delay or payload dev axis fits the
    #: reference runs up to 1.7 noise floors worse, a rigid one's 0.02
    #: (docs/identification.md "Stop 83"); a LuGre axis's only 0.07, but
    #: its read-out refit (reference LuGre 337) stopped at 3.7 noise floors
    #: on training with 4-sub-step slopes, within 1.2 with 10
    #: (`tests/test_read_out_global.py`; docs/diagnosis.md "Stop 84").
    fine_slopes: ClassVar[bool] = False

    def __init__(self, params: Mapping[str, float], dt: float = 1e-3):
        self.check_params(params)
        self.params = {k: float(v) for k, v in self.completed(params).items()}
        self.dt = dt
        self.reset()

    @classmethod
    def completed(cls, params: Mapping[str, object]) -> dict[str, object]:
        """`params` in `param_names` order, the left-out `defaults` filled in."""
        return {k: params[k] if k in params else cls.defaults[k] for k in cls.param_names}

    @classmethod
    def check_params(cls, params: Mapping[str, object]) -> None:
        """Check that `params` names exactly `param_names` (those with
        `defaults` may be left out).

        Raises:
            ParameterError: a missing or unknown parameter (the first one,
                with the nearest name and the expected ones).
        """
        missing = [p for p in cls.param_names if p not in params and p not in cls.defaults]
        unknown = [p for p in params if p not in cls.param_names]
        if missing or unknown:
            bad = (missing or unknown)[0]
            raise ParameterError(
                f"effect '{cls.name}': {'missing' if missing else 'unknown'} parameter "
                f"'{bad}'{nearest(bad, cls.param_names)}; expects {', '.join(cls.param_names)}"
            )

    def reset(self) -> None:
        """Clear internal state (delay lines, filter states)."""

    def substep_columns(self, dt: float, m: int) -> dict[str, object]:
        """The kernel's coefficients of an `in_substeps` effect, by the names of
        `isp_twin.model.substep_model.STATE_COLUMNS` (floats or arrays (P,));
        none for an effect that acts through its hooks."""
        return {}

    def command(self, u: float) -> float:
        return u

    def acceleration(self, angle: float, rate: float) -> float:
        return 0.0

    def measure(self, rate: float) -> float:
        return rate

    def command_run(self, u: np.ndarray) -> np.ndarray:
        """`command` over a whole run: u (rows, N) [digits] -> (rows, N).

        By default `command` sample after sample, in order (a hook with
        state); a hook without state, or a linear one, overrides this with
        array operations that give the same numbers.
        """
        return _per_sample(self.command, u)

    def command_run_split(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray | float]:
        """`command_run` for a model that resolves the sample (sub-steps):
        the command (rows, N) [digits] and the fraction of each sample [0, 1)
        (a float or (rows,)) over which the *previous* sample's command still
        acts. By default `command_run` and 0: a hook of the sample alone."""
        return self.command_run(u), 0.0

    def measure_run(self, rate: np.ndarray) -> np.ndarray:
        """`measure` over a whole run: rate (rows, N) [rad/s] -> (rows, N),
        sample after sample by default (see `command_run`)."""
        return _per_sample(self.measure, rate)

    def fusion_gain(self) -> np.ndarray | float:
        """What the fused angle's smoothing took off the gyro's deflection
        from the motor side, per unit of the fusion window's mean of the
        measured rate's derivative [rad per rad/s^2 = s^2], per row or a
        float (`isp_twin.identification.side_angle.with_side_angle`): the
        fused angle plus it times that mean is the payload's angle less the
        deflection the sub-stepped model takes off itself. 0: no deflection."""
        return 0.0

    #: Whether `true_rate` maps a reading back (a sensor error known at rest).
    maps_readings: ClassVar[bool] = False

    def true_rate(self, reading: float) -> float:
        """The true rate a reading means at rest or in steady motion (the
        inverse of `measure` where it has one; the reading itself by default)."""
        return reading

    #: Whether the diagnosis refines every one of the `guesses`, not only the
    #: one a simulation at the current rate parameters ranks best: for a
    #: parameter whose guesses lie in separate basins a local fit cannot move
    #: between (cogging's period), which a base far from the noise cannot rank.
    every_guess_refined: ClassVar[bool] = False

    @classmethod
    def refined_starts(cls, ctx) -> list[dict[str, float]]:
        """Starts the diagnosis refines with the rate parameters beside the
        best of the `guesses` (none by default): for an effect whose guesses
        a simulation at the current rate parameters cannot rank (LuGre: its
        bristle force trades against the friction levels those hold), each
        with the levels lowered by its `sliding_friction_rad_s2` and
        `drive_taken_digits` (`isp_twin.diagnosis.candidates`)."""
        return []

    #: The parameter that trades against the friction levels on the training
    #: runs (None: none does): raised, with every regime's static and Coulomb
    #: levels lowered by what it adds (`sliding_friction_rad_s2`,
    #: `drive_taken_digits`), it changes nothing the runs can see where drive
    #: and motion keep one sign. Where a held-out run is given the diagnosis
    #: places it along that trade by the held-out run
    #: (`isp_twin.diagnosis.trade`).
    trade_parameter: ClassVar[str | None] = None

    @classmethod
    def sliding_friction_rad_s2(cls, params: Mapping[str, float]) -> float:
        """The friction the effect adds in steady sliding, against the motion
        [rad/s^2] (0 by default; LuGre's bristle force): a base fitted without
        the effect carries it in its Coulomb and static levels."""
        return 0.0

    @classmethod
    def drive_taken_digits(cls, params: Mapping[str, float]) -> float:
        """The command the effect takes off a drive beyond it [digits] (0 by
        default; a dead zone's width): in steady sliding a base fitted
        without the effect carries the motor gain times it in its Coulomb
        and static levels (`isp_twin.diagnosis.candidates`)."""
        return 0.0

    @classmethod
    def negligible(cls, params: Mapping[str, float], u_peak: float) -> str:
        """Why these parameters are too small to be this effect on runs whose
        largest |command| is `u_peak`, or "" (the default: never)."""
        return ""

    @classmethod
    def undetermined(cls, params: Mapping[str, float], travel_rad: float) -> str:
        """Why runs that travel `travel_rad` [rad] (largest minus smallest
        angle) cannot tell these parameters as this effect from another, or
        "" (the default: they can)."""
        return ""


def _per_sample(hook, x: np.ndarray) -> np.ndarray:
    """`hook` on each column of x (rows, N), in sample order."""
    out = np.empty_like(x, dtype=float)
    for k in range(x.shape[1]):
        out[:, k] = hook(x[:, k])
    return out


def elementwise_run(hook, x: np.ndarray) -> np.ndarray:
    """A memoryless hook over a whole run x (rows, N) in one call: the hook's
    per-row parameters (P,) broadcast along the last axis, so the run is
    passed as (N, rows)."""
    return np.asarray(hook(np.asarray(x, dtype=float).T), dtype=float).T


def true_rates(effects, reading):
    """The rate a gyro `reading` means through the sensor errors among
    `effects` (`Effect.true_rate` of those that `Effect.maps_readings`), the
    last hook undone first; `reading` itself where there is none."""
    for e in reversed([e for e in effects if e.maps_readings]):
        reading = e.true_rate(reading)
    return reading
