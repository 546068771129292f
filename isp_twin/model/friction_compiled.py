"""Eq. 5 compiled by numba from its one source, the scalar form in `isp_twin.model.friction`.

The compiled kernels (`isp_twin.experiments.closed_loop_kernel`, `isp_twin.model.substep_model`)
call these instead of writing the friction law again. Each function of
`friction.SCALAR_LAW` is compiled from its Python code object in a copy of the
friction module's namespace where the others are their compiled forms, so one
may call another (`sliding` calls `stribeck`).

numba's cache checks only the time stamp of the file that defines a cached
kernel: an edit to friction.py alone would leave a cached kernel on the old
law. Each kernel module therefore caches a small probe of the law next to its
kernels and compares it with `python_law` at import (`law_probe_cases`);
on a mismatch it recompiles them.
"""

from __future__ import annotations

import types

import numba
import numpy as np

from isp_twin.model import friction

__all__ = [
    "side_of",
    "regime_of",
    "stribeck",
    "sliding",
    "stiction",
    "probe",
    "law_probe_cases",
    "python_law",
]


def _compile_scalar_law() -> dict[str, numba.core.dispatcher.Dispatcher]:
    namespace = dict(vars(friction))
    compiled = {}
    for name in friction.SCALAR_LAW:
        f = namespace[name]
        compiled[name] = namespace[name] = numba.njit(
            types.FunctionType(f.__code__, namespace, f.__name__, f.__defaults__)
        )
    return compiled


_LAW = _compile_scalar_law()
side_of = _LAW["side_of"]
regime_of = _LAW["regime_of"]
stribeck = _LAW["stribeck"]
sliding = _LAW["sliding"]
stiction = _LAW["stiction"]


@numba.njit
def probe(cases: np.ndarray) -> np.ndarray:
    """The compiled law on `law_probe_cases` rows (angle, rate, drive, Ts, Tc, alpha).

    Returns rows (side, regime, stribeck, sliding (0 at rest), stiction), as
    `python_law`. A kernel module wraps it in a function cached beside its
    kernels, so the wrapper goes stale with them.
    """
    out = np.empty((cases.shape[0], 5))
    for i in range(cases.shape[0]):
        angle, rate, drive = cases[i, 0], cases[i, 1], cases[i, 2]
        ts, tc, al = cases[i, 3], cases[i, 4], cases[i, 5]
        direction = rate if rate != 0.0 else drive
        side = side_of(angle, direction)
        out[i, 0] = side
        out[i, 1] = regime_of(side, direction)
        out[i, 2] = stribeck(abs(rate), ts, tc, al)
        out[i, 3] = sliding(rate, ts, tc, al) if rate != 0.0 else 0.0
        out[i, 4] = stiction(drive, ts)
    return out


def law_probe_cases() -> np.ndarray:
    """Probe rows (angle, rate, drive, Ts, Tc, alpha): both sides, all regimes, rest and moving."""
    rows = [
        (angle, rate, drive, 1.5, 0.6, alpha)
        for angle in (0.3, 0.0, -0.3)
        for rate in (0.2, -0.7, 0.0)
        for drive in (2.0, -2.0, 0.4, -0.4, 0.0)
        for alpha in (0.0, 3.0)
    ]
    return np.array(rows)


def python_law(cases: np.ndarray) -> np.ndarray:
    """A kernel module's probe, computed by `isp_twin.model.friction`'s scalar functions in Python.

    Rows (side, regime, stribeck, sliding (0 at rest), stiction) for the
    `law_probe_cases` rows (angle, rate, drive, Ts, Tc, alpha).
    """
    out = []
    for angle, rate, drive, ts, tc, al in cases.tolist():
        direction = rate if rate != 0.0 else drive
        side = friction.side_of(angle, direction)
        out.append(
            (
                side,
                friction.regime_of(side, direction),
                friction.stribeck(abs(rate), ts, tc, al),
                friction.sliding(rate, ts, tc, al) if rate != 0.0 else 0.0,
                friction.stiction(drive, ts),
            )
        )
    return np.array(out)
