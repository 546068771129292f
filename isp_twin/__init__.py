"""isp-twin: digital twin of a two-axis, four-gimbal inertially stabilized platform.

Implements Cong et al., "Isolation control for inertially stabilized platform
based on nonlinear friction compensation": the improved Stribeck friction law
(Eq. 5), the discrete axis model (Eq. 6), GA identification (Eq. 8-9), the
isolation metric (Eq. 10) and the friction feed-forward NFC (Eq. 11-14).
"""

__version__ = "0.1.0"

import os as _os
import sys as _sys
import warnings as _warnings


def _avx2() -> bool:
    """The CPU has AVX2 (Linux: /proc/cpuinfo; elsewhere: not known, False)."""
    try:
        with open("/proc/cpuinfo") as f:
            return any(line.startswith("flags") and " avx2" in line for line in f)
    except OSError:
        return False


# One BLAS thread unless the user says otherwise: the fits' matrices are small
# (12000 x 20), and on a shared 2-core machine OpenBLAS's thread pool made one
# such SVD 0.34 s instead of 0.007 s (measured; it dominated `identify`).
#
# One OpenBLAS kernel on every x86-64 machine with AVX2, unless the user says
# otherwise: OpenBLAS picks its kernels by CPU, the kernels round the fits'
# SVD and least squares differently, and the trust region then takes another
# path on a cost that stick/slip makes piecewise. Seen: on an AVX-512 CPU
# (kernel SkylakeX) reference clean seed 12 identified without the restart at
# the noise reached 1.12 noise sigmas held out where the Haswell and Zen
# kernels stop at 2.0 (tests/test_restart_at_noise.py). With the kernel
# pinned, a scenario and seed give the same numbers on any such machine.
#
# Set before numpy is first imported by the package; an explicit setting wins.
_BLAS_PIN = {"OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
if _avx2():
    _BLAS_PIN["OPENBLAS_CORETYPE"] = "Haswell"

#: The OpenBLAS settings above that cannot act: numpy, and OpenBLAS with it,
#: was loaded before this package and the environment had not set them.
_TOO_LATE = (
    tuple(v for v in _BLAS_PIN if v.startswith("OPENBLAS") and v not in _os.environ)
    if "numpy" in _sys.modules
    else ()
)
for _var, _value in _BLAS_PIN.items():
    _os.environ.setdefault(_var, _value)

# A script that loads numpy first runs OpenBLAS's own kernel and threads:
# its fits round differently and can take another path than the command's
# (reference sensor bias seed 413: diagnose right at 2.51 noise floors from
# the command, `none` at 81 from a script that imported numpy first;
# docs/diagnosis.md "Stop 70"). Said once, at import, not silently.
if _TOO_LATE:
    _warnings.warn(
        "isp_twin: numpy was imported before isp_twin, so "
        + " and ".join(_TOO_LATE)
        + " could not be set: identify/diagnose may round differently from the isp-twin "
        + "command (import isp_twin first, or set them in the environment)",
        RuntimeWarning,
        stacklevel=2,
    )
del _os, _sys, _var, _value
