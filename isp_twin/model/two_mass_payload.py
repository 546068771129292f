"""The two-mass payload of Stop 17 B, now the library's `resonance`.

`TwoMassResonance` was the two-mass form before it was registered; since
Stop 18 R (docs/diagnosis.md) `isp_twin.model.effects.resonance.Resonance`
is that form (``payload_fraction`` > 0, ``coupling`` 1 for a gyro on the
payload) and this name is kept for code written against it.
"""

from __future__ import annotations

from isp_twin.model.effects.resonance import Resonance

__all__ = ["TwoMassResonance"]

TwoMassResonance = Resonance
