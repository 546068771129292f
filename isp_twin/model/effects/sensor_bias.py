"""Gyro errors: a constant bias and a scale-factor error."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect, elementwise_run


class SensorBias(Effect):
    """``rate_measured = bias_rad_s + (1 + scale) * rate``.

    The scale error is invisible in rate data alone (it rescales gain and
    friction alike); it is estimated against the independent angle sensor
    (`guesses`) and held fixed while the rest is refitted (`frozen`).

    Parameters: ``bias_rad_s`` [rad/s], ``scale`` [1] (0 = exact).
    """

    name = "sensor_bias"
    param_names = ("bias_rad_s", "scale")
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"bias_rad_s": 0.0, "scale": 0.0}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "bias_rad_s": (-1.0, 1.0),
        "scale": (-0.5, 0.5),
    }
    #: Parameters not refined by the least-squares refit (see class doc).
    frozen: ClassVar[tuple[str, ...]] = ("scale",)

    def measure(self, rate):
        p = self.params
        return p["bias_rad_s"] + (1.0 + p["scale"]) * rate

    def measure_run(self, rate):
        """Without state: the whole run in one call."""
        return elementwise_run(self.measure, rate)

    maps_readings = True

    def true_rate(self, reading):
        p = self.params
        return (reading - p["bias_rad_s"]) / (1.0 + p["scale"])

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """Regress the gyro on the angle sensor's rate over 20-sample windows
        (averaging keeps the angle noise from biasing the slope)."""
        win = 20
        n = (ctx.rate.size - 1) // win
        if n < 3:
            return [{"bias_rad_s": 0.0, "scale": 0.0}]
        idx = np.arange(n) * win
        # Windows must not straddle two runs.
        idx = idx[ctx.run_id[idx] == ctx.run_id[idx + win]]
        if idx.size < 3:
            return [{"bias_rad_s": 0.0, "scale": 0.0}]
        gyro = np.array([ctx.rate[i + 1 : i + win + 1].mean() for i in idx])
        enc = (ctx.angle[idx + win] - ctx.angle[idx]) / (win * ctx.dt)
        slope, bias = np.polyfit(enc, gyro, 1)
        return [{"bias_rad_s": float(bias), "scale": float(np.clip(slope - 1.0, -0.5, 0.5))}]
