"""An independent reference simulator of one gimbal axis (tests, benchmarks, trying the tool).

It shares no code with the project's models (`friction`, `axis_model`,
`effects`, `twin`, `parameters`): it imports only the standard library, numpy,
scipy, numba (its integrator is compiled) and `isp_twin.errors`, so fitting the project's model to its data tests
the fit rather than the code that made the data. See docs/reference_simulator.md.

Modules: `axis` (continuous-time physics, integrator, stick logic, sensors),
`effects` (its own physics of each library effect), `draw` (random axes),
`excitation` (commands), `experiment` (the two training runs and the held-out
run of a drawn axis), `truth` (the truth in the project's conventions).
"""

from __future__ import annotations

from isp_twin.reference.axis import (
    REGIME_NAMES,
    Axis,
    ReferenceRun,
    RegimeFriction,
    Sensors,
    simulate,
)
from isp_twin.reference.draw import COMMAND_SCALE_DIGITS, EFFECT_NAMES, DrawnAxis, draw_axis
from isp_twin.reference.excitation import KINDS, Excitation
from isp_twin.reference.experiment import (
    HELD_OUT_DESIGNS,
    RUN_NAMES,
    ReferenceExperiment,
    design_experiment,
    regime_reach,
)
from isp_twin.reference.truth import rate_form, truth_record

__all__ = [
    "REGIME_NAMES",
    "Axis",
    "RegimeFriction",
    "Sensors",
    "ReferenceRun",
    "simulate",
    "COMMAND_SCALE_DIGITS",
    "EFFECT_NAMES",
    "DrawnAxis",
    "draw_axis",
    "KINDS",
    "Excitation",
    "RUN_NAMES",
    "HELD_OUT_DESIGNS",
    "ReferenceExperiment",
    "design_experiment",
    "regime_reach",
    "rate_form",
    "truth_record",
]
