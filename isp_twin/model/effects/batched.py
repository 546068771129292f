"""Effects evaluated for a batch of parameter sets at once (for fitting).

Every effect's hooks are written with numpy, so the same class serves one
parameter set (floats, the twin's per-step use) and P sets (arrays of shape
(P,), the fast axis model inside least squares).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from isp_twin.model.effects import Effect, effect_class

__all__ = ["make_batched"]


def make_batched(name: str, params: Mapping[str, np.ndarray], dt: float) -> Effect:
    """An effect whose parameters are arrays of shape (P,) (or scalars).

    Raises:
        ParameterError: unknown effect or a missing/unknown parameter.
    """
    cls = effect_class(name)
    cls.check_params(params)
    effect = cls.__new__(cls)
    effect.params = {k: np.asarray(v, dtype=float) for k, v in cls.completed(params).items()}
    effect.dt = dt
    effect.reset()
    return effect
