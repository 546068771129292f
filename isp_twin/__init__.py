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


def _avx2() -> bool:
    """The CPU has AVX2 (Linux: /proc/cpuinfo; elsewhere: not known, False)."""
    try:
        with open("/proc/cpuinfo") as f:
            return any(line.startswith("flags") and " avx2" in line for line in f)
    except OSError:
        return False


# One OpenBLAS kernel on every x86-64 machine with AVX2, unless the user says
# otherwise: OpenBLAS picks its kernels by CPU, the kernels round the fits'
# SVD and least squares differently, and the trust region then takes another
# path on a cost that stick/slip makes piecewise. Seen: on an AVX-512 CPU
# (kernel SkylakeX) reference clean seed 12 identified without the restart at
# the noise reached 1.12 noise sigmas held out where the Haswell and Zen
# kernels stop at 2.0 (tests/test_restart_at_noise.py). With the kernel
# pinned, a scenario and seed give the same numbers on any such machine.
if _avx2():
    _os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")
del _os, _var
