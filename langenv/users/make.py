"""A user chosen by name (the env's ``users`` argument)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from langenv.errors import ConfigError
from langenv.users.base import CallableUser, User
from langenv.users.listening import ListeningUser
from langenv.users.replay import ReplayUser
from langenv.users.synthetic import SyntheticUser

__all__ = ["make_user"]


def make_user(users: Any, session: str | Path | None) -> User:
    """The person of ``LangCtrlEnv(users=..., session=...)``: a user chosen by name
    (``"synthetic"``, ``"listening"``, ``"replay"`` with ``session``), a :class:`User` as it
    is, or a callable wrapped in :class:`CallableUser`.

    Raises:
        ConfigError: naming ``users`` (or the missing ``session``).
    """
    if isinstance(users, str):
        if users == "synthetic":
            return SyntheticUser()
        if users == "listening":
            return ListeningUser()
        if users == "replay":
            if session is None:
                raise ConfigError("users='replay' needs session=PATH to a session CSV")
            return ReplayUser.from_csv(session)
        raise ConfigError(
            f"users must be 'synthetic', 'listening', 'replay', a User or a callable; got {users!r}"
        )
    if hasattr(users, "reset") and hasattr(users, "force"):
        return users
    if callable(users):
        return CallableUser(users)
    raise ConfigError(f"users must be 'synthetic', 'replay', a User or a callable; got {users!r}")
