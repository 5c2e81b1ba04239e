"""A sweep file: what to run, as data, checked whole before anything starts.

A sweep file is YAML::

    grid:                                   # the Cartesian product of these lists
      policy: [ac, lc-noap, lc]             # required: policy specs, as langctrl compare --policies
      exercise: [external_rotation]         # default: the study's (eval.sweep.exercises)
      phrase_graph: [lc, graphs/short.yaml] # for the policies that choose phrases
      decision_hz: [500]                    # default: each policy's own rate
      lc.k_c: [5.0, 10.0, 20.0]             # a parameter of policy lc (eval.overrides)
      env.admittance.damping: {linspace: [20.0, 40.0, 3]}   # a parameter of the env
    sample:                                 # optional: n random points of a parameter space
      n: 8
      seed: 0
      space:
        lc.k_em: {uniform: [0.0, 2.0]}
        env.deadband: {loguniform: [1.0, 10.0]}
    users: {synthetic: 20, first_seed: 0}   # one user set, or a list of them
    batch_size: 16                          # optional: sessions per task (default: chosen)

=====================  =====================================================================
key                    meaning
=====================  =====================================================================
``grid.policy``        policy specs (``langctrl compare --policies`` names); a ``ppo:PATH``
                       is named ``ppo`` (or ``ppo-STEM``) in rows and parameter names
``grid.exercise``      exercise names (:data:`~eval.sweep.exercises.SWEEP_EXERCISES`)
``grid.phrase_graph``  shipped graph names or YAML paths; only the policies that choose phrases
                       (LC variants, learned) vary over them, instead of the exercise's graph;
                       AC and LC-noAP say the exercise's one wording. A row's ``graph`` names
                       the graph its session spoke
``grid.decision_hz``   decision rates (dividing 500)
``grid.POLICY.NAME``   values of a ``float`` parameter of that policy (``lc.k_c``, ``lc.gains.k_p``,
                       ``lc.k_em``); sessions of other policies do not vary over it
``grid.env.NAME``      values of an env parameter (``env.admittance.damping``, ``env.w_em``)
values                 a list, or ``{linspace: [lo, hi, n]}``, ``{logspace: [lo, hi, n]}`` (n
                       points, ends included), ``{range: [start, stop, step]}`` (stop excluded)
``sample.space``       per parameter ``{uniform: [lo, hi]}``, ``{loguniform: [lo, hi]}`` or
                       ``{choice: [v, ...]}``; ``sample.n`` points drawn with ``sample.seed``,
                       crossed with the grid (a parameter is in the grid or the space, not both)
``users``              ``{synthetic: N, first_seed: S}`` (user ``i`` is ``s{S+i}`` with seed
                       ``S + i``, as in ``eval.compare``), ``{listening: N, first_seed: S,
                       params: {latency: 1.2, ...}}`` (the same people listening to the robot,
                       ``params`` fields of ``ListeningParams``; ``eval.users``) or ``{sessions:
                       DIR, pattern: GLOB, first_seed: S}`` (recorded sessions replayed);
                       optional ``name``
=====================  =====================================================================

Every session of one user has that user's seed, whatever the policy or parameters: comparisons
are paired, and a session's row equals the row ``eval.compare`` gives the same policy and user.
:func:`load_spec` reports every problem of a file at once (:class:`~eval.sweep.errors.SweepError`,
naming the file, each key and its line).
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from eval.sweep.errors import SweepError
from eval.sweep.exercises import DEFAULT_EXERCISE, SWEEP_EXERCISES
from langenv.validation import yaml_text

__all__ = [
    "COORDINATES",
    "Distribution",
    "Param",
    "SampleSpec",
    "SweepSpec",
    "UserSet",
    "load_spec",
]

#: The grid's keys other than parameters, in the order of a row's coordinates.
COORDINATES = ("policy", "exercise", "phrase_graph", "decision_hz")

_TOP_KEYS = ("grid", "sample", "users", "batch_size")
_RANGES = ("linspace", "logspace", "range")
_DISTRIBUTIONS = ("uniform", "loguniform", "choice")
#: Most sessions one sweep file may expand to.
MAX_SESSIONS = 10_000_000


@dataclass(frozen=True)
class Param:
    """A swept parameter.

    Attributes:
        name: As written in the file (``"lc.k_c"``); the row's column.
        scope: The policy name it belongs to, or ``"env"``.
        path: Its full path in the policy or env (``"gains.k_c"``, ``"admittance.damping"``).
        values: Grid values (empty for a sampled parameter).
    """

    name: str
    scope: str
    path: str
    values: tuple[float, ...] = ()


@dataclass(frozen=True)
class Distribution:
    """A sampled parameter's distribution: ``kind`` in uniform, loguniform, choice."""

    param: Param
    kind: str
    args: tuple[float, ...]

    def draw(self, rng: np.random.Generator) -> float:
        """One value from ``rng`` (one draw, whatever the kind: the stream stays aligned)."""
        u = float(rng.random())
        if self.kind == "uniform":
            lo, hi = self.args
            return lo + (hi - lo) * u
        if self.kind == "loguniform":
            lo, hi = self.args
            return float(math.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * u))
        return self.args[min(int(u * len(self.args)), len(self.args) - 1)]


@dataclass(frozen=True)
class SampleSpec:
    """``n`` random points of ``space``, drawn in file order from ``seed``."""

    n: int
    seed: int
    space: tuple[Distribution, ...]

    def points(self) -> list[dict[str, float]]:
        """The ``n`` points: parameter name -> value; the same for the same spec, always."""
        rng = np.random.default_rng(self.seed)
        return [{d.param.name: d.draw(rng) for d in self.space} for _ in range(self.n)]


@dataclass(frozen=True)
class UserSet:
    """Users of a sweep: ``count`` synthetic users, or the session CSVs of ``directory``.

    Attributes:
        name: The set's name (its coordinate ``users`` in rows).
        users: ``(user name, seed, session CSV path or None)`` per user.
        listening: For listening people (``{listening: N}``): their
            :class:`~langenv.users.ListeningParams`; None otherwise.
    """

    name: str
    users: tuple[tuple[str, int, str | None], ...]
    listening: Any = None


@dataclass(frozen=True)
class SweepSpec:
    """A checked sweep file (:func:`load_spec`).

    Attributes:
        file: The file it was read from.
        policies: Policy specs, with their names in rows (``policy_spec -> policy``).
        exercises: Exercise names.
        phrase_graphs: Graphs for the policies that choose phrases (None: the exercise's).
        decision_hz: Rates (None: each policy's own).
        params: Grid parameters.
        sample: Random points, or None.
        users: User sets.
        batch_size: Sessions per task, or None to choose.
        raw: The file's data as loaded (resolved: paths absolute), for ``DIR/sweep.yaml``.
    """

    file: Path
    policies: Mapping[str, str]
    exercises: tuple[str, ...]
    phrase_graphs: tuple[str | None, ...]
    decision_hz: tuple[int | None, ...]
    params: tuple[Param, ...]
    sample: SampleSpec | None
    users: tuple[UserSet, ...]
    batch_size: int | None
    raw: Mapping[str, Any] = field(repr=False)

    @property
    def param_names(self) -> tuple[str, ...]:
        """Every parameter's name: the grid's, then the sampled ones."""
        sampled = tuple(d.param.name for d in self.sample.space) if self.sample else ()
        return tuple(p.name for p in self.params) + sampled


class _Problems:
    """Every problem of a file, each with its key and line, raised at once."""

    def __init__(self, file: Path, lines: Mapping[str, int]) -> None:
        self.file, self.lines, self.items = file, lines, []  # type: ignore[var-annotated]

    def add(self, key: str, detail: str) -> None:
        top = key.split("[")[0]
        line = self.lines.get(key) or self.lines.get(top) or self.lines.get(top.split(".")[0])
        self.items.append((f"{key} (line {line})" if line else key, detail))

    def raise_any(self) -> None:
        if self.items:
            raise SweepError(self.file, self.items[0][0], self.items[0][1], self.items[1:])


def _key_lines(text: str) -> dict[str, int]:
    """Line (1-based) of each key of the file's top two levels (``"grid.lc.k_c"``)."""
    import yaml

    lines: dict[str, int] = {}
    try:
        root = yaml.compose(text)  # its errors are load_spec's, named there
    except yaml.YAMLError:
        return lines
    if isinstance(root, yaml.MappingNode):
        for k, v in root.value:
            lines[str(k.value)] = k.start_mark.line + 1
            if isinstance(v, yaml.MappingNode):
                for k2, _ in v.value:
                    lines[f"{k.value}.{k2.value}"] = k2.start_mark.line + 1
    return lines


def load_spec(path: str | Path) -> SweepSpec:
    """Read and check a sweep file; nothing runs.

    Checks: known keys; policies load (``ppo:PATH`` model files exist); exercises, phrase graphs
    and rates exist; every learned model can act on the graph it would speak; each parameter is
    a ``float`` field of its policy or the env, named once, and each of its values is accepted
    by the dataclass it sets; ranges and distributions are well formed; the grid and every user
    set are non-empty.

    Raises:
        SweepError: every problem found, one line each (file, key, line, what is allowed).
    """
    import yaml

    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
        data = yaml.safe_load(yaml_text(text, file))
    except OSError as exc:
        raise SweepError(file, "", f"cannot read the sweep file ({exc.strerror or exc})") from None
    except yaml.YAMLError as exc:
        raise SweepError(file, "", f"not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise SweepError(file, "", "a sweep file is a mapping with keys " + ", ".join(_TOP_KEYS))
    problems = _Problems(file, _key_lines(text))
    for key in data:
        if key not in _TOP_KEYS:
            problems.add(str(key), f"unknown key; known: {', '.join(_TOP_KEYS)}")
    grid = data.get("grid")
    if not isinstance(grid, dict) or not grid:
        problems.add("grid", "empty grid: give at least grid.policy, a list of policies")
        problems.raise_any()
    assert isinstance(grid, dict)
    policies = _policies(grid.get("policy"), problems)
    exercises = _names(grid, "exercise", [DEFAULT_EXERCISE], problems, _check_exercise)
    graphs = _names(grid, "phrase_graph", [None], problems, _check_graph)
    rates = _names(grid, "decision_hz", [None], problems, _check_rate)
    if not problems.items:
        _check_spoken(policies, exercises, graphs, problems)
    loaded = {name: pol for name, pol in policies.values() if pol is not None}
    params = []
    for key, values in grid.items():
        if key in COORDINATES:
            continue
        param = _param(str(key), loaded, policies, problems, "grid")
        if param is not None:
            vals = _values(f"grid.{key}", values, problems)
            if vals:
                checked = [v for v in vals if _check_value(param, v, loaded, problems, "grid")]
                if len(checked) == len(vals):
                    params.append(Param(param.name, param.scope, param.path, tuple(vals)))
    sample = _sample(data.get("sample"), loaded, policies, problems, {p.name for p in params})
    users = _user_sets(data.get("users"), problems)
    batch = data.get("batch_size")
    if batch is not None and (isinstance(batch, bool) or not isinstance(batch, int) or batch < 1):
        problems.add("batch_size", f"must be an integer >= 1, got {batch!r}")
    problems.raise_any()
    return SweepSpec(
        file=file,
        policies={spec: name for spec, (name, _) in policies.items()},
        exercises=tuple(exercises),
        phrase_graphs=tuple(graphs),
        decision_hz=tuple(rates),
        params=tuple(params),
        sample=sample,
        users=tuple(users),
        batch_size=batch,
        raw=_resolved(data, grid),
    )


def _resolved(data: Mapping[str, Any], grid: Mapping[str, Any]) -> dict[str, Any]:
    """The file's data with phrase graph and session paths absolute (what ran, wherever)."""
    out = dict(data)
    out["grid"] = dict(grid)
    if "phrase_graph" in grid:
        out["grid"]["phrase_graph"] = [_graph_ref(g) for g in grid["phrase_graph"]]
    users = data["users"] if isinstance(data["users"], list) else [data["users"]]
    out["users"] = [
        {**u, "sessions": str(Path(u["sessions"]).resolve())} if "sessions" in u else dict(u)
        for u in users
    ]
    return out


def _graph_ref(graph: Any) -> Any:
    from langenv.speech.graph import SHIPPED_GRAPHS

    if graph is None or str(graph) in SHIPPED_GRAPHS:
        return graph
    return str(Path(graph).resolve())


def _policies(value: Any, problems: _Problems) -> dict[str, tuple[str, Any]]:
    """policy spec -> (its name in rows, the loaded policy or None when it failed)."""
    from eval.compare import policy_names
    from policies import load_policy

    if not isinstance(value, list) or not value:
        problems.add("grid.policy", "empty grid: give a list of policies, e.g. [ac, lc-noap, lc]")
        return {}
    specs = [str(v) for v in value]
    if len(set(specs)) != len(specs):
        problems.add("grid.policy", f"lists a policy twice: {specs}")
    out: dict[str, tuple[str, Any]] = {}
    for spec, name in policy_names(list(dict.fromkeys(specs))).items():
        try:
            out[spec] = (name, load_policy(spec))
        except (KeyError, FileNotFoundError, ValueError, OSError) as exc:
            detail = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
            problems.add("grid.policy", f"unknown policy {spec!r}: {detail}")
            out[spec] = (name, None)
    return out


def _names(
    grid: Mapping[str, Any], key: str, default: list[Any], problems: _Problems, check: Any
) -> list[Any]:
    if key not in grid:
        return default
    value = grid[key]
    if not isinstance(value, list) or not value:
        problems.add(f"grid.{key}", "empty grid: give a non-empty list")
        return default
    for v in value:
        detail = check(v)
        if detail:
            problems.add(f"grid.{key}", detail)
    if len(set(map(str, value))) != len(value):
        problems.add(f"grid.{key}", f"lists a value twice: {value}")
    return [v if v is None else (str(v) if key != "decision_hz" else v) for v in value]


def _check_exercise(name: Any) -> str | None:
    if str(name) not in SWEEP_EXERCISES:
        return f"unknown exercise {name!r}; known: {', '.join(SWEEP_EXERCISES)}"
    return None


def _check_graph(graph: Any) -> str | None:
    from langenv.errors import LangEnvError
    from langenv.speech.graph import SHIPPED_GRAPHS, PhraseGraph

    if str(graph) in SHIPPED_GRAPHS:
        return None
    try:
        PhraseGraph.load(Path(str(graph)))
    except (LangEnvError, OSError) as exc:
        known = ", ".join(SHIPPED_GRAPHS)
        return f"phrase graph {graph!r} is neither shipped ({known}) nor a valid file: {exc}"
    return None


def _check_spoken(
    policies: Mapping[str, tuple[str, Any]],
    exercises: list[Any],
    graphs: list[Any],
    problems: _Problems,
) -> None:
    """Every policy that adapts to the graph it speaks (a learned model) can act on the graph
    of every exercise and ``phrase_graph`` of the grid: one that cannot is a problem of
    ``grid.policy``, found before any worker starts."""
    from langenv.errors import LangEnvError
    from langenv.exercise.script import speak
    from policies import load_policy

    for spec, (_name, policy) in policies.items():
        if policy is None or not callable(getattr(policy, "use_graph", None)):
            continue
        for exercise in exercises:
            for graph in graphs:
                try:
                    speak(load_policy(spec), exercise, graph)  # a fresh one: use_graph adapts it
                except LangEnvError as exc:
                    problems.add("grid.policy", f"{spec} on {exercise}: {exc}")


def _check_rate(hz: Any) -> str | None:
    if isinstance(hz, bool) or not isinstance(hz, int) or hz <= 0 or 500 % hz:
        return f"decision_hz must be a positive integer dividing 500, got {hz!r}"
    return None


def _param(
    key: str,
    loaded: Mapping[str, Any],
    policies: Mapping[str, tuple[str, Any]],
    problems: _Problems,
    section: str,
) -> Param | None:
    """The parameter named ``key`` (``POLICY.NAME`` or ``env.NAME``), or None (a problem added)."""
    from eval.overrides import resolve_env_param, resolve_policy_param
    from langenv.errors import ConfigError

    scope, dot, name = key.partition(".")
    where = f"{section}.{key}"
    if not dot or not name:
        known = ", ".join(COORDINATES)
        problems.add(where, f"unknown parameter: give one of {known}, POLICY.NAME or env.NAME")
        return None
    try:
        if scope == "env":
            return Param(key, "env", resolve_env_param(name))
        if scope in loaded:
            return Param(key, scope, resolve_policy_param(loaded[scope], name))
    except ConfigError as exc:
        problems.add(where, str(exc))
        return None
    names = sorted({n for n, _ in policies.values()})
    if scope not in names:
        problems.add(
            where,
            f"unknown parameter: {scope!r} is neither env nor a policy of grid.policy "
            f"({', '.join(names)})",
        )
    return None


def _check_value(
    param: Param, value: float, loaded: Mapping[str, Any], problems: _Problems, section: str
) -> bool:
    """Whether the dataclass that takes ``param`` accepts ``value`` (else a problem added)."""
    from eval.overrides import apply_policy_params, env_kwargs_with
    from langenv.errors import ConfigError

    try:
        if param.scope == "env":
            env_kwargs_with({}, [(param.path, value)])
        else:
            apply_policy_params(loaded[param.scope], [(param.path, value)])
    except ConfigError as exc:
        problems.add(f"{section}.{param.name}", f"bad range: value {value!r} refused: {exc}")
        return False
    return True


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    v = float(value)
    return v if math.isfinite(v) else None


def _values(key: str, value: Any, problems: _Problems) -> list[float]:
    """The grid values of a parameter: a list, or a range (checked: ``bad range``)."""
    if isinstance(value, list):
        if not value:
            problems.add(key, "empty grid: give at least one value")
            return []
        nums = [_number(v) for v in value]
        if any(n is None for n in nums):
            problems.add(key, f"values must be finite numbers, got {value}")
            return []
        if len(set(nums)) != len(nums):
            problems.add(key, f"lists a value twice: {value}")
            return []
        return [n for n in nums if n is not None]
    if isinstance(value, dict) and len(value) == 1 and next(iter(value)) in _RANGES:
        kind, args = next(iter(value.items()))
        return _range(key, kind, args, problems)
    problems.add(
        key, f"give a list of values or one of {{{', '.join(_RANGES)}: [...]}}, got {value!r}"
    )
    return []


def _range(key: str, kind: str, args: Any, problems: _Problems) -> list[float]:
    nums = [_number(a) for a in args] if isinstance(args, list) and len(args) == 3 else []
    if len(nums) != 3 or any(n is None for n in nums):
        problems.add(
            key,
            f"bad range: {kind} takes three finite numbers ([lo, hi, n] or [start, stop, step]), "
            f"got {args!r}",
        )
        return []
    a, b, c = (float(n) for n in nums)  # type: ignore[arg-type]
    if kind == "range":
        if c <= 0 or a >= b:
            problems.add(
                key,
                f"bad range: range [start, stop, step] needs start < stop and step > 0, got {args}",
            )
            return []
        count = math.ceil((b - a) / c - 1e-9)
        if count > 10_000:
            problems.add(key, f"bad range: {count} values (at most 10000)")
            return []
        return [a + i * c for i in range(count)]
    if not (c == int(c) and 2 <= c <= 10_000) or a >= b or (kind == "logspace" and a <= 0):
        need = "0 < lo < hi" if kind == "logspace" else "lo < hi"
        problems.add(
            key,
            f"bad range: {kind} [lo, hi, n] needs {need} and an integer n in [2, 10000], "
            f"got {args}",
        )
        return []
    fn = np.geomspace if kind == "logspace" else np.linspace
    return [float(v) for v in fn(a, b, int(c))]


def _sample(
    value: Any,
    loaded: Mapping[str, Any],
    policies: Mapping[str, tuple[str, Any]],
    problems: _Problems,
    in_grid: set[str],
) -> SampleSpec | None:
    if value is None:
        return None
    if not isinstance(value, dict) or set(value) - {"n", "seed", "space"}:
        problems.add("sample", "give {n: N, seed: S, space: {PARAM: {uniform: [lo, hi]}, ...}}")
        return None
    n, seed, space = value.get("n"), value.get("seed", 0), value.get("space")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        problems.add("sample.n", f"must be an integer >= 1, got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        problems.add("sample.seed", f"must be an integer >= 0, got {seed!r}")
    if not isinstance(space, dict) or not space:
        problems.add("sample.space", "empty grid: give at least one parameter to sample")
        return None
    dists = []
    for key, spec in space.items():
        where = f"sample.space.{key}"
        if key in in_grid:
            problems.add(where, "is also in grid: a parameter is swept or sampled, not both")
            continue
        param = _param(str(key), loaded, policies, problems, "sample.space")
        if param is None:
            continue
        dist = _distribution(where, param, spec, problems)
        if dist is not None:
            ends = dist.args
            if all(_check_value(param, v, loaded, problems, "sample.space") for v in ends):
                dists.append(dist)
    if problems.items:
        return None
    assert isinstance(n, int) and isinstance(seed, int)
    return SampleSpec(n, seed, tuple(dists))


def _distribution(where: str, param: Param, spec: Any, problems: _Problems) -> Distribution | None:
    if not (isinstance(spec, dict) and len(spec) == 1 and next(iter(spec)) in _DISTRIBUTIONS):
        problems.add(where, f"give one of {{{', '.join(_DISTRIBUTIONS)}: [...]}}, got {spec!r}")
        return None
    kind, args = next(iter(spec.items()))
    nums = [_number(a) for a in args] if isinstance(args, list) else [None]
    if not nums or any(v is None for v in nums):
        problems.add(where, f"bad range: {kind} takes a list of finite numbers, got {args!r}")
        return None
    vals = tuple(float(v) for v in nums if v is not None)
    if kind != "choice" and (
        len(vals) != 2 or vals[0] >= vals[1] or (kind == "loguniform" and vals[0] <= 0)
    ):
        need = "0 < lo < hi" if kind == "loguniform" else "lo < hi"
        problems.add(where, f"bad range: {kind} [lo, hi] needs {need}, got {args}")
        return None
    return Distribution(param, kind, vals)


def _user_sets(value: Any, problems: _Problems) -> list[UserSet]:
    if value is None:
        problems.add("users", "give a user set: {synthetic: N, first_seed: S} or {sessions: DIR}")
        return []
    items = value if isinstance(value, list) else [value]
    if not items:
        problems.add("users", "empty grid: give at least one user set")
    sets = []
    for i, item in enumerate(items):
        where = "users" if not isinstance(value, list) else f"users[{i}]"
        user_set = _user_set(where, item, problems)
        if user_set is not None:
            sets.append(user_set)
    names = [s.name for s in sets]
    if len(set(names)) != len(names):
        problems.add("users", f"two user sets have one name: {names} (give each a name)")
    return sets


def _user_set(where: str, item: Any, problems: _Problems) -> UserSet | None:
    if not isinstance(item, dict):
        problems.add(
            where, f"give {{synthetic: N, first_seed: S}} or {{sessions: DIR}}, got {item!r}"
        )
        return None
    allowed = {"synthetic", "listening", "params", "sessions", "pattern", "first_seed", "name"}
    for key in set(item) - allowed:
        problems.add(f"{where}.{key}", f"unknown key; known: {', '.join(sorted(allowed))}")
    seed = item.get("first_seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        problems.add(f"{where}.first_seed", f"must be an integer >= 0, got {seed!r}")
        return None
    kinds = [k for k in ("synthetic", "listening", "sessions") if k in item]
    if len(kinds) != 1:
        problems.add(where, "give exactly one of synthetic: N, listening: N and sessions: DIR")
        return None
    if "params" in item and kinds[0] != "listening":
        problems.add(f"{where}.params", "sets listening people's parameters: give listening: N")
        return None
    if kinds[0] in ("synthetic", "listening"):
        kind = kinds[0]
        count = item[kind]
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 1_000_000:
            problems.add(
                f"{where}.{kind}",
                f"empty grid: must be an integer in [1, 1000000], got {count!r}",
            )
            return None
        listening = None
        label = f"{kind}:{count}@{seed}"
        if kind == "listening":
            listening = _listening(f"{where}.params", item.get("params", {}), problems)
            if listening is None:
                return None
            if item.get("params"):
                label += "[" + ",".join(f"{k}={v}" for k, v in item["params"].items()) + "]"
        name = str(item.get("name", label))
        users = tuple((f"s{seed + i}", seed + i, None) for i in range(count))
        return UserSet(name, users, listening)
    return _session_set(where, item, seed, problems)


def _listening(where: str, value: Any, problems: _Problems) -> Any:
    """The listening people's parameters from ``params`` (a mapping of fields), or None."""
    from langenv.errors import ConfigError
    from langenv.users import ListeningParams
    from langenv.validation import dataclass_from_dict

    try:
        return dataclass_from_dict(ListeningParams, value, "ListeningParams")
    except (ConfigError, TypeError) as exc:
        problems.add(where, str(exc))
        return None


def _session_set(
    where: str, item: Mapping[str, Any], seed: int, problems: _Problems
) -> UserSet | None:
    from langenv.errors import SessionDataError
    from langenv.users import load_session

    directory, pattern = Path(str(item["sessions"])), str(item.get("pattern", "*.csv"))
    if not directory.is_dir():
        problems.add(f"{where}.sessions", f"{directory} is not a directory")
        return None
    paths = sorted(directory.glob(pattern))
    if not paths:
        problems.add(f"{where}.pattern", f"empty grid: no files match {pattern!r} in {directory}")
        return None
    for p in paths:
        try:
            load_session(p)
        except SessionDataError as exc:
            problems.add(f"{where}.sessions", str(exc))
            return None
    name = str(item.get("name", f"sessions:{directory.name}/{pattern}"))
    if not re.fullmatch(r"[^\n]+", name):
        problems.add(f"{where}.name", "must be one line")
    return UserSet(name, tuple((p.stem, seed + i, str(p.resolve())) for i, p in enumerate(paths)))
