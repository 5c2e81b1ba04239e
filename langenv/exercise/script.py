"""Which phrase graph a policy speaks: the exercise's, chosen by the policy's graph role.

A policy brings a rule, not a script (SPEC §9). It declares a *graph role*
(:data:`~langenv.exercise.spec.GRAPH_ROLES`) and the exercise maps the role to a graph
(:meth:`~langenv.exercise.spec.Exercise.graph_for`):

=========  ============================================  ==========================================
role       spoken                                        policies
=========  ============================================  ==========================================
``graph``  the exercise's ``script.graph`` (the study's  those that choose phrases: LC, its
           exercise: ``default``), or an override        variants, learned aligners
``single`` the exercise's ``script.single`` (the         AC and LC-noAP: the paper's baselines,
           study's exercise: ``lc-noap``), always        one wording by design
=========  ============================================  ==========================================

An override (``--graph`` of ``eval.compare`` and ``langctrl play``) replaces the graph of a policy
that chooses phrases; the one wording of the baselines belongs to the exercise (write an exercise
file with another ``script.single`` to change it). :func:`speak` resolves the graph and hands it
to the policy's optional ``use_graph(spoken)`` hook, where a policy that must adapt to the graph
does so or refuses with a named error (a learned model whose observation holds one block per
choice: :meth:`policies.learned.PPOPolicy.use_graph`). A policy never speaks the data it was
trained on unless told to.

Tables name a graph by :func:`graph_label`: a shipped graph's name, or the YAML's path relative to
the package's assets, to the working directory, or by its file name only: never a path of the
machine that ran it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from langenv.errors import ConfigError
from langenv.exercise.registry import resolve_exercise
from langenv.exercise.spec import GRAPH_ROLES, Exercise

__all__ = [
    "ASSETS_DIR",
    "SpokenGraph",
    "graph_choices",
    "graph_label",
    "graph_role",
    "speak",
    "spoken_graph",
]

ASSETS_DIR = Path(__file__).resolve().parents[1] / "assets"
"""The package's data (shipped graphs, exercises and their scripts): labels are relative to it."""

_LEGACY_SINGLE = ("ac", "lc-noap")
_CHOICES: dict[tuple[str, int, int], int] = {}


@dataclass(frozen=True)
class SpokenGraph:
    """The phrase graph one policy speaks on one exercise.

    Attributes:
        ref: What the env's ``phrase_graph`` takes: a shipped graph's name or a YAML path.
        label: How tables name it (:func:`graph_label`).
        role: The policy's graph role (:data:`~langenv.exercise.spec.GRAPH_ROLES`).
        overridden: Whether an override chose it rather than the exercise.
        max_children: The graph's largest number of choices at a phrase (at least 1).
    """

    ref: str
    label: str
    role: str
    overridden: bool
    max_children: int


def graph_role(policy: Any) -> str:
    """The graph role a policy declares (its ``graph_role``).

    A policy written before roles existed declares none; its ``phrase_graph`` says it: ``"ac"``
    and ``"lc-noap"`` mean ``"single"``, anything else ``"graph"`` (it speaks the exercise's
    phrase graph, not its own file).

    Raises:
        ConfigError: a role that is not one of :data:`~langenv.exercise.spec.GRAPH_ROLES`.
    """
    role = getattr(policy, "graph_role", None)
    if role is None:
        own = str(getattr(policy, "phrase_graph", "")).replace("_", "-")
        role = "single" if own in _LEGACY_SINGLE else "graph"
    if role not in GRAPH_ROLES:
        name = getattr(policy, "name", type(policy).__name__)
        raise ConfigError(
            f"policy {name!r}: graph_role must be one of {sorted(GRAPH_ROLES)}, got {role!r}"
        )
    return str(role)


def graph_label(ref: str | Path) -> str:
    """How a table names the phrase graph ``ref``, the same on every machine.

    A shipped graph by its name (an alias by the first name of its file: ``"lc"`` is
    ``"default"``, ``"ac"`` is ``"lc-noap"``); a YAML under the package's assets relative to
    :data:`ASSETS_DIR` (``exercises/scripts/hand_to_mouth_lc.yaml``); a relative path as given; an
    absolute one relative to the working directory when under it, else by its file name.
    """
    from langenv.speech.graph import SHIPPED_GRAPHS

    key = str(ref).replace("_", "-")
    if key in SHIPPED_GRAPHS:
        target = SHIPPED_GRAPHS[key]
        return next(name for name, path in SHIPPED_GRAPHS.items() if path == target)
    path = Path(ref)
    resolved = path.resolve()
    if resolved.is_relative_to(ASSETS_DIR):
        return resolved.relative_to(ASSETS_DIR).as_posix()
    if not path.is_absolute():
        return path.as_posix()
    cwd = Path.cwd().resolve()
    return resolved.relative_to(cwd).as_posix() if resolved.is_relative_to(cwd) else path.name


def graph_choices(ref: str | Path) -> int:
    """The largest number of choices at a phrase of graph ``ref`` (at least 1); a file is read
    once per process (again when it changes on disk).

    Raises:
        PhraseGraphError: a bad graph file (naming it); ConfigError: an unknown shipped name.
    """
    from langenv.speech.graph import PhraseGraph, graph_path

    path = graph_path(ref).resolve()
    try:
        st = path.stat()
        key = (str(path), st.st_mtime_ns, st.st_size)
    except OSError:
        key = (str(path), 0, 0)  # PhraseGraph.load names the file
    found = _CHOICES.get(key)
    if found is None:
        found = _CHOICES[key] = max(1, PhraseGraph.load(path).max_children)
    return found


def spoken_graph(
    role: str, exercise: str | Path | Exercise | None = None, override: str | Path | None = None
) -> SpokenGraph:
    """The graph a policy of graph role ``role`` speaks on ``exercise`` (None: the study's).

    Args:
        role: The policy's graph role.
        exercise: A shipped exercise's name, a YAML path or an exercise.
        override: A graph (shipped name or YAML path) instead of the exercise's, for a policy
            that chooses phrases (role ``"graph"``).

    Raises:
        ConfigError: an unknown role, or an override for role ``"single"``;
            PhraseGraphError: a bad graph file.
    """
    if role not in GRAPH_ROLES:
        raise ConfigError(f"graph role must be one of {sorted(GRAPH_ROLES)}, got {role!r}")
    if override is not None and role != "graph":
        raise ConfigError(
            f"a phrase graph override ({override}) applies to the policies that choose phrases; "
            "AC and LC-noAP say the exercise's one wording (script.single): give them another "
            "in an exercise file"
        )
    if override is None:
        ex = resolve_exercise(exercise)
        if (warning := ex.script_warning(role)) is not None:
            warnings.warn(warning.removeprefix("warning: "), UserWarning, stacklevel=2)
        ref = ex.graph_for(role)
    else:
        ref = str(override)
    return SpokenGraph(ref, graph_label(ref), role, override is not None, graph_choices(ref))


def speak(
    policy: Any,
    exercise: str | Path | Exercise | None = None,
    override: str | Path | None = None,
) -> SpokenGraph:
    """Resolve the graph ``policy`` speaks on ``exercise`` and prepare the policy for it.

    The graph is :func:`spoken_graph` of the policy's :func:`graph_role`; ``override`` counts
    for a policy that chooses phrases only (a one-wording policy ignores it). A policy with a
    ``use_graph(spoken)`` method is handed the result, which may adapt it (and its
    ``env_kwargs``) or raise; build the env after this call.

    Raises:
        ConfigError: a bad role; PhraseGraphError: a bad graph file; whatever the policy's
            ``use_graph`` raises (a :class:`~langenv.errors.GraphChoicesError` for a learned
            model that cannot act on the graph).
    """
    role = graph_role(policy)
    spoken = spoken_graph(role, exercise, override if role == "graph" else None)
    hook = getattr(policy, "use_graph", None)
    if callable(hook):
        hook(spoken)
    return spoken
