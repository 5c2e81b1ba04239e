"""Simulated users: the person holding the handle (SPEC §5 "Users").

- :class:`User`: the protocol the environment calls every tick (``reset(rng)``, ``force(...)``).
- :class:`SyntheticUser`: seeded random resistance episodes, calibrated against the study's
  sessions (``assets/users/synthetic.yaml``, written by ``langctrl calibrate``).
- :class:`ListeningUser`: a synthetic person who responds to what the robot says (each heard
  wording's intent, the speech running ahead or behind); :class:`ListeningParams`.
- :class:`PerturbedUser`: a synthetic person plus a drawn behaviour the analytic aligners do not
  model (speeds up late, stops and restarts, tremor, lagged cooperation).
- :class:`ReplayUser`: the force that reproduces a recorded session's cooperation.
- :class:`CallableUser`: any ``fn(t, hand_velocity, tangent) -> (3,)``.
- :func:`load_session`, :func:`load_sessions`: recorded-session CSVs (:class:`Session`).
"""

from __future__ import annotations

from langenv.users.base import (
    DEFAULT_ALPHA,
    DEFAULT_DEADBAND,
    DEFAULT_F_MAX,
    CallableUser,
    Listener,
    User,
    against_motion,
)
from langenv.users.listening import ListeningParams, ListeningUser
from langenv.users.perturbed import PERTURBATIONS, Perturbations, PerturbedUser
from langenv.users.replay import ReplayUser, invert_cooperation
from langenv.users.session_csv import Session, load_session, load_sessions
from langenv.users.synthetic import Episode, LogNormal, SyntheticUser, SyntheticUserParams

__all__ = [
    "DEFAULT_ALPHA",
    "DEFAULT_DEADBAND",
    "DEFAULT_F_MAX",
    "PERTURBATIONS",
    "CallableUser",
    "Episode",
    "Listener",
    "ListeningParams",
    "ListeningUser",
    "LogNormal",
    "Perturbations",
    "PerturbedUser",
    "ReplayUser",
    "Session",
    "SyntheticUser",
    "SyntheticUserParams",
    "User",
    "against_motion",
    "invert_cooperation",
    "load_session",
    "load_sessions",
]
