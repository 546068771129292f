"""The information criterion (BIC) both fits are compared by.

``BIC = M ln(SSE/M) + k ln M`` for M residual samples and k free parameters
(Gaussian errors of unknown variance, Schwarz 1978): a parameter must lower
the training SSE by a factor ``M^(1/M)`` per parameter to pay for itself.
Diagnose compares a candidate effect with the model without it
(`isp_twin.diagnosis.selection`); the model the parameter file gave is scored
the same way.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bic", "parameter_penalty"]

#: Smallest SSE taken into the logarithm (a perfect fit is not -inf).
_SSE_FLOOR = 1e-300


def parameter_penalty(n_params: float, n_samples: int) -> float:
    """The BIC's price of `n_params` parameters on `n_samples` samples: k ln M."""
    return float(n_params * np.log(max(n_samples, 2)))


def bic(sse: float, n_samples: int, n_params: int) -> float:
    """Bayesian information criterion of a least-squares fit [1].

    Args:
        sse: sum of squared residuals [residual unit^2].
        n_samples: residual samples M.
        n_params: free parameters k.
    """
    m = n_samples
    return float(m * np.log(max(sse, _SSE_FLOOR) / m) + parameter_penalty(n_params, m))
