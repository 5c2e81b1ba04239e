"""The jobs' simulated people: ``--users synthetic:N`` or ``listening:N``, and ``--listening``.

One home for what ``--users`` may say (``langctrl compare``, ``fidelity``, ``exercises``):

* ``synthetic:N``: N seeded synthetic people (:class:`~langenv.users.SyntheticUser`), person
  ``i`` drawn with seed ``SEED + i``;
* ``listening:N``: the same N people, each listening to what the robot says
  (:class:`~langenv.users.ListeningUser`): person ``i`` is synthetic person ``i`` plus a response
  to the words, so a run of each pairs person for person.

``--listening KEY=VALUE,...`` sets :class:`~langenv.users.ListeningParams` fields for
``listening:N`` (``--listening latency=1.2,comply=0.4``); it is refused with ``synthetic:N``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

__all__ = ["USER_KINDS", "UserSpec", "parse_users"]

USER_KINDS = ("synthetic", "listening")
"""What ``--users KIND:N`` may name."""


@dataclass(frozen=True)
class UserSpec:
    """``--users KIND:N`` (and ``--listening``) parsed.

    Attributes:
        kind: One of :data:`USER_KINDS`.
        count: N, >= 1.
        listening: The listening people's parameters (``listening`` only; None otherwise).
    """

    kind: str
    count: int
    listening: Any = None

    def model(self) -> Any:
        """The person the env resets with each seed: a :class:`~langenv.users.ListeningUser`
        for ``listening``, None for ``synthetic`` (the env's own synthetic person)."""
        if self.kind != "listening":
            return None
        from langenv.users import ListeningUser

        return ListeningUser(self.listening)

    def names(self, seed: int) -> list[tuple[str, int]]:
        """``(name, seed)`` of each person: ``s{seed + i}`` (the same names for both kinds: the
        same people, with or without listening)."""
        return [(f"s{seed + i}", seed + i) for i in range(self.count)]


def parse_users(text: str, listening: str | None = None, max_count: int = 10_000) -> UserSpec:
    """``--users`` and ``--listening`` of a job.

    Raises:
        ValueError: saying what is wrong: not ``KIND:N`` with a kind of :data:`USER_KINDS` and
            ``1 <= N <= max_count``, ``--listening`` without ``listening:N``, or a bad
            ``--listening`` (:meth:`ListeningParams.parse
            <langenv.users.ListeningParams.parse>`'s message).
    """
    kind, _, count = str(text).partition(":")
    kinds = " or ".join(f"{k}:N" for k in USER_KINDS)
    if kind not in USER_KINDS or not re.fullmatch(r"[0-9]+", count) or int(count) < 1:
        raise ValueError(f"--users must be {kinds} with N >= 1, got {text!r}")
    if int(count) > max_count:
        raise ValueError(f"--users: at most {max_count} people per run, got {count}")
    if kind != "listening":
        if listening is not None:
            raise ValueError(f"--listening sets listening people: give --users listening:{count}")
        return UserSpec(kind, int(count))
    from langenv.users import ListeningParams

    params = ListeningParams.parse(listening) if listening is not None else ListeningParams()
    return UserSpec(kind, int(count), params)
