"""Discrete PI controller of the inner rate loops (paper Sect. 4.1).

The form, per sample k (T = 1 ms), with error e = reference - measurement,
is by default (rig knob pi_form) the series ("ideal") PI with a per-sample
integrator::

    s[k] = s[k-1] + e[k]                (integrator: a plain sum, per sample)
    u[k] = kp * (e[k] + ki * s[k])

i.e. the integral gain is kp*ki per sample (paper: 3.568*0.0714 = 0.255
without NFC, 3.0*0.15 = 0.45 with it). The paper does not print its PI form;
docs/calibration.md explains why this reading, and not the parallel
``kp*e + ki*s``, is the one that gives a stable loop with the paper's
isolation. Units are whatever the caller uses consistently: the rate loop
feeds gyro counts and gets amplifier digits (Kp = 3.568 digits per count).

Anti-windup (the paper's "bound of control quantity" says nothing about the
integrator; a bound without anti-windup makes the loop overshoot for seconds
after a saturation): while the bounded output is saturated, the integrator
only accepts errors that drive the output back inside (conditional integration).
"""

from __future__ import annotations

import math

__all__ = ["PIController"]


class PIController:
    """Discrete PI, series ``u = kp*(e + ki*sum(e))`` or parallel ``u = kp*e + ki*sum(e)``,
    with conditional anti-windup.

    Args:
        kp: proportional gain [output unit per input unit].
        ki: integral gain per sample: relative to kp (series) or absolute
            (parallel) [1 per sample, or output unit per input unit per sample].
        limit: output magnitude at which the integrator stops winding up
            (math.inf for none).
        form: "series" (the twin's reading, rig knob pi_form) or "parallel".
    """

    def __init__(self, kp: float, ki: float, limit: float = math.inf, form: str = "series"):
        if not (math.isfinite(kp) and math.isfinite(ki)):
            raise ValueError(f"PI gains must be finite, got kp={kp}, ki={ki}")
        if ki < 0 or kp < 0:
            raise ValueError(f"PI gains must be >= 0, got kp={kp}, ki={ki}")
        if not limit > 0:
            raise ValueError(f"PI output limit must be > 0, got {limit}")
        if form not in ("series", "parallel"):
            raise ValueError(f"PI form must be 'series' or 'parallel', got {form!r}")
        self.kp = float(kp)
        self.ki = float(ki)
        self.form = form
        self._series = form == "series"
        self.limit = float(limit)
        self.reset()

    def reset(self) -> None:
        """Zero the integrator."""
        self.integral = 0.0

    def _output(self, error: float, integral: float) -> float:
        if self._series:
            return self.kp * (error + self.ki * integral)
        return self.kp * error + self.ki * integral

    def step(self, error: float) -> float:
        """One sample: the output for the error ``e[k]``."""
        s = self.integral + error
        u = self._output(error, s)
        if abs(u) > self.limit and u * error > 0.0:
            # Saturated and the error pushes further out: freeze the integrator.
            u = self._output(error, self.integral)
        else:
            self.integral = s
        return u
