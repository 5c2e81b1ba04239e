"""The control loop of SPEC §1: trajectory, guide, variable admittance, cooperation, motion ETC.

Everything here is pure Python/NumPy (no MuJoCo): the virtual closed loop can be simulated on its
own (:func:`~langenv.control.virtual_loop.simulate_virtual`) and the arm engineer plugs the same
objects into the 500 Hz tick (:mod:`langenv.motion.tick`).
"""

from __future__ import annotations

from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.cooperation import CooperationFilter, force_for_cooperation
from langenv.control.guide import Guide, GuideState
from langenv.control.motion_etc import FastETC, reference_etc
from langenv.control.trajectory import (
    ArcSegment,
    LineSegment,
    Trajectory,
    default_exercise,
    line,
)
from langenv.control.virtual_loop import VirtualRun, simulate_virtual

__all__ = [
    "AdmittanceParams",
    "ArcSegment",
    "CooperationFilter",
    "FastETC",
    "Guide",
    "GuideState",
    "LineSegment",
    "Trajectory",
    "VariableAdmittance",
    "VirtualRun",
    "default_exercise",
    "force_for_cooperation",
    "line",
    "reference_etc",
    "simulate_virtual",
]
