"""Effects evaluated for a batch of parameter sets at once (for fitting).

Every effect's hooks are written with numpy, so the same class serves one
parameter set (floats, the twin's per-step use) and P sets (arrays of shape
(P,), the fast axis model inside least squares).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from isp_twin.effects import EFFECTS, Effect
from isp_twin.errors import ParameterError, nearest

__all__ = ["make_batched"]


def make_batched(name: str, params: Mapping[str, np.ndarray], dt: float) -> Effect:
    """An effect whose parameters are arrays of shape (P,) (or scalars).

    Raises:
        ParameterError: unknown effect or a missing/unknown parameter.
    """
    try:
        cls = EFFECTS[name]
    except KeyError:
        raise ParameterError(
            f"unknown effect '{name}'{nearest(name, EFFECTS)}; known: {', '.join(sorted(EFFECTS))}"
        ) from None
    missing = [p for p in cls.param_names if p not in params]
    unknown = [p for p in params if p not in cls.param_names]
    if missing or unknown:
        bad = (missing or unknown)[0]
        raise ParameterError(
            f"effect '{name}': {'missing' if missing else 'unknown'} parameter '{bad}'; "
            f"expects {', '.join(cls.param_names)}"
        )
    effect = cls.__new__(cls)
    effect.params = {k: np.asarray(params[k], dtype=float) for k in cls.param_names}
    effect.dt = dt
    effect.reset()
    return effect
