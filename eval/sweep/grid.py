"""A sweep's sessions, in a fixed order, each with its coordinates, seed and ``session_id``.

:func:`expand` is a pure function of the :class:`~eval.sweep.spec.SweepSpec`: the same file
gives the same sessions in the same order, with the same ids, on any machine. A session's seed is
its user's (``first_seed + i``), never a worker's or a position's, so its row is the same for any
backend, worker count or batch size; ``session_id`` (16 hex digits of a SHA-256 of the
coordinates and the seed) keys ``--resume`` and de-duplication.

Order: policy, exercise, phrase graph, rate, grid parameters (in file order, last fastest),
sample point, user set, user. A policy varies only over its own parameters and the env's; one
that does not choose phrases (AC, LC-noAP: graph role ``single``) says the exercise's one wording
(its ``phrase_graph`` coordinate is empty); the row's ``graph`` column names the graph each
session spoke.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from eval.compare import Job, policy_role
from eval.sweep.exercises import job_exercise
from eval.sweep.spec import Param, SweepSpec

__all__ = ["SweepSession", "expand", "session_id"]

Coordinates = Mapping[str, Any]


@dataclass(frozen=True)
class SweepSession:
    """One session of a sweep.

    Attributes:
        session_id: Stable id (:func:`session_id`).
        coords: Coordinates, in row order: ``policy``, ``policy_spec``, ``exercise``,
            ``phrase_graph`` (None: the exercise's), ``decision_hz`` (None: the policy's own),
            each parameter (None where it does not apply), ``sample`` (None without sampling),
            ``users`` (the set's name), ``user``.
        seed: The user's seed (the env's reset seed).
        job: The episode to run (:func:`eval.compare.run_episode`: no files written).
    """

    session_id: str
    coords: Coordinates
    seed: int
    job: Job


def session_id(coords: Coordinates, seed: int) -> str:
    """16 hex digits of the SHA-256 of the coordinates and seed (canonical JSON)."""
    payload = json.dumps({"coords": dict(coords), "seed": seed}, sort_keys=True, allow_nan=False)
    return hashlib.sha256(payload.encode("utf-8")).hexdigest()[:16]


def _applies(param: Param, policy: str) -> bool:
    return param.scope in ("env", policy)


def expand(spec: SweepSpec) -> list[SweepSession]:
    """Every session of ``spec``, in the module's fixed order."""
    return list(_sessions(spec))


def _sessions(spec: SweepSpec) -> Iterator[SweepSession]:
    points = spec.sample.points() if spec.sample is not None else [None]
    sampled = {d.param.name: d.param for d in spec.sample.space} if spec.sample else {}
    for policy_spec, policy in spec.policies.items():
        graphs = spec.phrase_graphs if policy_role(policy_spec) == "graph" else (None,)
        grid = [p for p in spec.params if _applies(p, policy)]
        mine = {n: p for n, p in sampled.items() if _applies(p, policy)}
        own_points = points if mine else [None]
        for exercise, graph, hz in itertools.product(spec.exercises, graphs, spec.decision_hz):
            for combo in itertools.product(*(p.values for p in grid)):
                values = {p.name: v for p, v in zip(grid, combo, strict=True)}
                for k, point in enumerate(own_points):
                    drawn = {n: point[n] for n in mine} if point is not None else {}
                    params = {**values, **drawn}
                    base = {
                        "policy": policy,
                        "policy_spec": policy_spec,
                        "exercise": exercise,
                        "phrase_graph": graph,
                        "decision_hz": hz,
                        **{n: params.get(n) for n in spec.param_names},
                        "sample": k if point is not None else None,
                    }
                    resolved = {**{p.name: p for p in grid}, **mine}
                    job_params = sorted(
                        (resolved[n].path, v)
                        for n, v in params.items()
                        if resolved[n].scope != "env"
                    )
                    env_params = sorted(
                        (resolved[n].path, v)
                        for n, v in params.items()
                        if resolved[n].scope == "env"
                    )
                    for user_set in spec.users:
                        person = _person(user_set)
                        for user, seed, session in user_set.users:
                            coords = {**base, "users": user_set.name, "user": user}
                            job = Job(
                                policy_spec,
                                user,
                                seed,
                                session,
                                "",
                                audio=False,
                                figures=False,
                                decision_hz=hz,
                                phrase_graph=graph,
                                name=policy,
                                params=tuple(job_params),
                                env_params=tuple(env_params),
                                save_log=False,
                                user_model=person,
                                **job_exercise(exercise),
                            )
                            yield SweepSession(session_id(coords, seed), coords, seed, job)


def _person(user_set: Any) -> Any:
    """The person a user set's sessions reset with: a listening one for ``{listening: N}``,
    None (the env's synthetic person, or a replay) otherwise."""
    if user_set.listening is None:
        return None
    from langenv.users import ListeningUser

    return ListeningUser(user_set.listening)
