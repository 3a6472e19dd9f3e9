"""Forward simulation of a DIWire-class bender and a round wire (issue 6).

Public API: :class:`SimParams` (params JSON), :func:`simulate`,
:func:`pin_command_for_angle` (the inverse, used by the G-code generator),
:class:`Effect` and the effect catalogue :data:`EFFECTS`.
"""

from cvmeasure.sim.effects import EFFECT_NAMES, EFFECTS, Effect, parse_effect
from cvmeasure.sim.model import SimResult, max_reachable_deg, pin_command_for_angle, simulate
from cvmeasure.sim.params import SimParams, params_from_json, params_to_json

__all__ = [
    "EFFECT_NAMES",
    "EFFECTS",
    "Effect",
    "parse_effect",
    "SimResult",
    "simulate",
    "pin_command_for_angle",
    "max_reachable_deg",
    "SimParams",
    "params_from_json",
    "params_to_json",
]
