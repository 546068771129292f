"""The truth of a reference axis written in the project's conventions.

Eq. 6 of the paper, as the project writes it (`RateParams`), is per regime
``omega[k] = pole omega[k-1] + gain u[k-1] - sign * (coulomb + (static -
coulomb) exp(-alpha |omega[k-1]|))`` with pole [1], gain [rad/s per digit per
sample], static and coulomb [rad/s per sample], alpha [s/rad], regimes in the
order R+, R-, L+, L- (written again here, not imported).

The continuous axis ``J dw/dt = Km u - eta w - F`` sampled with a zero-order
hold of period T maps to

    pole = exp(-T eta / J),  gain = Km (1 - pole) / eta,
    static = Ts (1 - pole) / eta,  coulomb = Tc (1 - pole) / eta,  alpha = alpha

(with the per-regime multipliers of eta and Km). This is exact at the sample
instants for a rigid axis with a point-sampled gyro while friction is constant
over a sample (sliding with ``alpha |dw| << 1`` per sample, no stop inside the
sample); it is an approximation where the Stribeck term changes within a
sample, at stick/breakaway instants, and for the default averaged gyro, whose
reading lags the point value by half a sample (a term in u[k] of size about
gain/2 appears; relative error of order T / (2 J/eta)).

Effects are written in the project's parameter names (`isp_twin.model.effects`):
torques become accelerations torque / J [rad/s^2] with J the total inertia.
The project's discrete model adds such an acceleration as ``accel * T`` per
sample; the exact zero-order-hold factor would be ``(1 - pole) J / (eta T)``,
reported per regime as ``zoh_factor`` so a user can see how far the two are
apart for a fast axis (0.90 for J/eta = 5 ms, 0.9995 for 1 s).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from isp_twin.reference.axis import REGIME_NAMES, Axis, Sensors

__all__ = ["rate_form", "truth_record"]

_DEG = math.pi / 180.0


def rate_form(axis: Axis, dt: float = 1e-3) -> dict[str, dict[str, float]]:
    """Per regime name, the Eq. 6 rate-form values (SI, see module doc) and zoh_factor."""
    out = {}
    j = axis.inertia_kg_m2
    for name, r in zip(REGIME_NAMES, axis.regimes):
        eta = axis.viscous_nm_s * r.viscous_scale
        km = axis.motor_gain_nm_per_digit * r.gain_scale
        pole = math.exp(-dt * eta / j)
        per_torque = (1.0 - pole) / eta  # rad/s per sample per N·m
        out[name] = {
            "pole": pole,
            "gain": km * per_torque,
            "static": r.static_nm * per_torque,
            "coulomb": r.coulomb_nm * per_torque,
            "alpha": r.alpha_s_rad,
            "zoh_factor": per_torque * j / dt,
        }
    return out


def truth_record(
    axis: Axis,
    effects: Sequence[object],
    sensors: Sensors,
    *,
    dt: float = 1e-3,
    substeps: int = 10,
) -> dict:
    """Everything a fit can be judged against, as plain data (YAML/JSON-ready)."""
    rf = rate_form(axis, dt)
    return {
        "sample_time_s": dt,
        "integration_step_s": dt / substeps,
        "regime_order": list(REGIME_NAMES),
        "physical": _physical(axis),
        "rate_form": {
            "units": "pole 1, gain rad/s per digit per sample, static/coulomb rad/s per "
            "sample, alpha s/rad, zoh_factor 1",
            "discretization": "zero-order hold of the rigid axis, friction held over the "
            "sample (exact for point-sampled rate while sliding; see docs/reference_simulator.md)",
            "regimes": rf,
        },
        "paper_form": _paper_form(rf),
        "effects": [
            {"name": e.name, "params": e.truth(axis.inertia_kg_m2), "physical": _fields(e)}
            for e in effects
        ],
        "sensors": {
            "gyro_noise_deg_s": sensors.gyro_noise_rad_s / _DEG,
            "gyro_noise_rad_s": sensors.gyro_noise_rad_s,
            "gyro_averaged": sensors.gyro_averaged,
            "resolver_bits": sensors.resolver_bits,
            "resolver_lsb_deg": sensors.resolver_lsb_rad / _DEG,
            "resolver_noise_deg": sensors.resolver_noise_rad / _DEG,
        },
    }


def _physical(axis: Axis) -> dict:
    """The axis in SI: inertia, viscous, motor gain, each regime's friction and scales."""
    return {
        "inertia_kg_m2": axis.inertia_kg_m2,
        "viscous_nm_s_rad": axis.viscous_nm_s,
        "motor_gain_nm_per_digit": axis.motor_gain_nm_per_digit,
        "time_constant_s": axis.time_constant_s,
        "regimes": {
            name: {
                "static_nm": r.static_nm,
                "coulomb_nm": r.coulomb_nm,
                "alpha_s_rad": r.alpha_s_rad,
                "viscous_scale": r.viscous_scale,
                "gain_scale": r.gain_scale,
            }
            for name, r in zip(REGIME_NAMES, axis.regimes)
        },
    }


def _paper_form(rf: dict[str, dict[str, float]]) -> dict:
    """The rate form in the paper's units (Table 2: deg/s per sample, 1/(deg/s))."""
    return {
        "units": "a 1, bKe (deg/s)/digit per sample, bTs and bTc deg/s per sample, alpha 1/(deg/s)",
        "regimes": {
            name: {
                "a": v["pole"],
                "bKe": v["gain"] / _DEG,
                "bTs": v["static"] / _DEG,
                "bTc": v["coulomb"] / _DEG,
                "alpha": v["alpha"] * _DEG,
            }
            for name, v in rf.items()
        },
    }


def _fields(effect: object) -> dict[str, float]:
    return {k: float(v) for k, v in vars(effect).items()}
