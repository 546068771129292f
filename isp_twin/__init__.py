"""isp-twin: digital twin of a two-axis, four-gimbal inertially stabilized platform.

Implements Cong et al., "Isolation control for inertially stabilized platform
based on nonlinear friction compensation": the improved Stribeck friction law
(Eq. 5), the discrete axis model (Eq. 6), GA identification (Eq. 8-9), the
isolation metric (Eq. 10) and the friction feed-forward NFC (Eq. 11-14).
"""

__version__ = "0.1.0"
