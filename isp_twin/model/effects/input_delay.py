"""A transport delay on the command (digital amplifier, bus latency)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from isp_twin.model.effects.base import Effect


class InputDelay(Effect):
    """The amplifier sees the command ``delay_s`` late (linear interpolation
    between samples for a fractional delay; the command before the start is
    taken as the first one).

    Parameters: ``delay_s`` [s], >= 0.
    """

    name = "input_delay"
    param_names = ("delay_s",)
    #: Parameters that make the effect do nothing.
    null: ClassVar[dict[str, float]] = {"delay_s": 0.0}
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"delay_s": (0.0, 0.05)}
    #: A fractional delay switches the command at a sub-step.
    fine_slopes = True

    def reset(self) -> None:
        steps = np.maximum(np.asarray(self.params["delay_s"], dtype=float), 0.0) / self.dt
        self._whole = np.floor(steps).astype(np.intp)
        self._frac = steps - self._whole
        self._hist = None
        self._length = int(np.max(self._whole)) + 2
        self._k = 0

    def command(self, u):
        u = np.asarray(u, dtype=float)
        if self._hist is None:
            shape = np.broadcast_shapes(u.shape, self._whole.shape)
            self._hist = np.broadcast_to(u, (self._length,) + shape).copy()
            self._cols = np.arange(shape[0]) if len(shape) == 1 else None
        # Ring buffer: row k % length holds the command of sample k.
        n = self._length
        self._hist[self._k % n] = u
        if self._hist.ndim == 1:
            now = self._hist[(self._k - self._whole) % n]
            before = self._hist[(self._k - self._whole - 1) % n]
        else:
            now = self._hist[(self._k - self._whole) % n, self._cols]
            before = self._hist[(self._k - self._whole - 1) % n, self._cols]
        self._k += 1
        return (1.0 - self._frac) * now + self._frac * before

    def command_run(self, u):
        """The same delay line over a whole run (rows, N) by indexing: sample
        k sees samples k - whole and k - whole - 1, the first one before the
        start."""
        now, frac = self.command_run_split(u)
        before = np.concatenate([now[:, :1], now[:, :-1]], axis=1)
        return (1.0 - frac[:, None]) * now + frac[:, None] * before

    def command_run_split(self, u):
        """The delay line in whole samples, and the fraction of the sample
        the command before still acts at its start: a delay of 4.4 samples
        switches the held command 0.4 into the sample, which a sub-stepped
        model resolves (a stick or breakaway inside the sample follows the
        switch, not the sample's mean command). The mean over the sample is
        `command_run`'s."""
        u = np.asarray(u, dtype=float)
        rows, n = u.shape
        whole = np.broadcast_to(self._whole, (rows,))[:, None]
        k = np.arange(n)[None, :]
        now = np.take_along_axis(u, np.maximum(k - whole, 0), axis=1)
        return now, np.broadcast_to(self._frac, (rows,)).copy()

    @classmethod
    def guesses(cls, ctx) -> list[dict[str, float]]:
        """A grid of delays, 0.5 to 40 samples (the best is refined)."""
        steps = np.concatenate([np.arange(0.5, 12.0, 0.5), np.arange(12.0, 41.0, 2.0)])
        return [
            {"delay_s": float(s * ctx.dt)} for s in steps if s * ctx.dt <= cls.bounds["delay_s"][1]
        ]
