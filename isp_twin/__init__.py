"""isp-twin: digital twin of a two-axis, four-gimbal inertially stabilized platform.

Implements Cong et al., "Isolation control for inertially stabilized platform
based on nonlinear friction compensation": the improved Stribeck friction law
(Eq. 5), the discrete axis model (Eq. 6), GA identification (Eq. 8-9), the
isolation metric (Eq. 10) and the friction feed-forward NFC (Eq. 11-14).
"""

__version__ = "0.1.0"

import os as _os

# One BLAS thread unless the user says otherwise: the fits' matrices are small
# (12000 x 20), and on a shared 2-core machine OpenBLAS's thread pool made one
# such SVD 0.34 s instead of 0.007 s (measured; it dominated `identify`). Set
# before numpy is first imported by the package; an explicit setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
del _os, _var
