"""Read an exercise file into an :class:`~langenv.exercise.spec.Exercise`, every problem at once.

The file's format is the table in :mod:`langenv.exercise.spec`. :func:`load_exercise` reads it
with ``yaml.safe_load``, refuses unknown keys, converts the file's units (m, deg, s) to SI once,
and gathers every problem it finds (kind, leg, point, detail; the leg's line in the file) into one
:class:`~langenv.errors.ExerciseError`, so an author fixes them in one pass. It checks the
format and the path's shape only; whether the arm can follow it safely is
:func:`~langenv.exercise.check.check_exercise`'s business (``langctrl exercise check``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from langenv.errors import ExerciseError
from langenv.exercise.spec import (
    LEG_KINDS,
    SPEED_RANGE,
    SWITCH_TOL_RANGE,
    Exercise,
    Leg,
    Problem,
)
from langenv.validation import suggest, yaml_text

__all__ = ["UNITS", "load_exercise"]

UNITS = {"length": "m", "angle": "deg", "time": "s"}
"""The units of an exercise file (the ``units`` key may state them; no others are accepted)."""

_TOP = frozenset({"name", "title", "units", "start", "speed", "switch_tol", "script", "legs"})
_REQUIRED = ("name", "title", "start", "legs")
_SCRIPT = frozenset({"graph", "single"})
_LEG = frozenset({"name", "tool", "waypoint", *LEG_KINDS})
_FIELDS = {
    "line": frozenset({"to"}),
    "arc": frozenset({"center", "axis", "angle"}),
    "spline": frozenset({"through", "tolerance"}),
}
_TOOL = frozenset({"turn", "axis"})


Where = tuple[str | int, ...]
"""A place in the file: the keys and list indexes down to it (``("legs", 0, "line", "to")``)."""


class _Problems(list[Problem]):
    """Problems found so far (a list with helpers), and the file's lines of its keys."""

    def __init__(self, lines: dict[Where, int] | None = None) -> None:
        super().__init__()
        self.lines = lines or {}

    def add(
        self,
        kind: str,
        detail: str,
        leg: str | None = None,
        point: int | None = None,
        at: Where | None = None,
    ) -> None:
        """Add a problem; ``at`` names the key it is about, whose line the detail then gives."""
        if at is not None and at in self.lines:
            detail = f"{detail} (line {self.lines[at]})"
        self.append(Problem(kind, leg, point, detail))

    def unknown(
        self, key: Any, known: frozenset[str], at: Where, leg: str | None = None, what: str = ""
    ) -> None:
        """An unknown key at ``at``, with the closest known one and all of them."""
        detail = (
            f"{what}unknown key {key!r}{suggest(key, known)}; known: {', '.join(sorted(known))}"
        )
        self.add("unknown_key", detail, leg, at=(*at, key))


def load_exercise(path: str | Path, *, unwritten_scripts: bool = False) -> Exercise:
    """Read, validate and build the exercise of a YAML file.

    Args:
        path: The exercise file (``.yaml``).
        unwritten_scripts: Accept ``script`` entries that name files not written yet (a
            script being authored against its exercise: ``speech author --exercise``); they
            stay the paths they name.

    Returns:
        The exercise (its ``trajectory`` built, in SI units).

    Raises:
        ExerciseError: naming the file and every problem found (``problems``: kind, leg, point,
            detail), e.g. an unreadable file, unknown or missing keys, bad numbers or vectors,
            a leg that is not exactly one shape, a degenerate shape, a spline not fitted within
            its tolerance, a phrase graph that does not exist.
    """
    path = Path(path)
    try:
        source = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or exc
        raise ExerciseError(
            [Problem("unreadable", None, None, f"cannot read: {reason}")], path
        ) from None
    import yaml

    try:
        data = yaml.safe_load(yaml_text(source, path))
    except yaml.YAMLError as exc:
        raise ExerciseError(
            [Problem("unreadable", None, None, f"invalid YAML: {exc}")], path
        ) from None
    keys, lines = _source_lines(source)
    found = _Problems(keys)
    if not isinstance(data, dict):
        found.add(
            "not_mapping", "the file must be a mapping of the keys " + ", ".join(sorted(_TOP))
        )
        raise ExerciseError(found, path)
    for key in sorted(set(data) - _TOP, key=str):
        found.unknown(key, _TOP, ())
    for key in _REQUIRED:
        if key not in data:
            found.add("missing_key", f"{key!r} is required")
    units = data.get("units", UNITS)
    if units != UNITS:
        found.add(
            "bad_units", f"units must be {UNITS} (SI lengths, degrees, seconds), got {units!r}"
        )
    fields: dict[str, Any] = {"path": path}
    for key in ("name", "title"):
        if key in data:
            if isinstance(data[key], str) and data[key].strip():
                fields[key] = data[key].strip()
            else:
                found.add("bad_value", f"{key} must be a non-empty string")
    if "start" in data:
        start = _vector(data["start"], "start", found, None)
        if start is not None:
            fields["start"] = start
    for key, what, (lo, hi) in (
        ("speed", "speed (m/s)", SPEED_RANGE),
        ("switch_tol", "switch_tol (m, rad)", SWITCH_TOL_RANGE),
    ):
        if key in data:
            value = _number(data[key], what, found, None)
            if value is not None and not lo <= value <= hi:
                found.add("bad_value", f"{what} must lie in [{lo}, {hi}], got {value}")
            elif value is not None:
                fields[key] = value
    fields.update(_script(data.get("script", {}), path, found, unwritten_scripts))
    fields["description"] = _comment_block(source)
    legs = _legs(data.get("legs"), found, lines, fields.get("start")) if "legs" in data else []
    if found:
        raise ExerciseError(found, path)
    try:
        return Exercise(legs=tuple(legs), **fields)
    except ExerciseError as exc:
        raise ExerciseError([_at_line(p, lines) for p in exc.problems], path) from None


def _source_lines(source: str) -> tuple[dict[Where, int], dict[str, int]]:
    """Lines (1-based) in the file: of each key and list item, by its place (:data:`Where`), and
    of each leg's mapping, by the leg's name (both empty where the file does not compose)."""
    import yaml

    try:
        root = yaml.compose(source)
    except yaml.YAMLError:
        return {}, {}
    out: dict[Where, int] = {}

    def walk(node: Any, at: Where) -> None:
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                if isinstance(k, yaml.ScalarNode):
                    key = (*at, k.value)
                    out.setdefault(key, k.start_mark.line + 1)
                    walk(v, key)
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                out[(*at, i)] = item.start_mark.line + 1
                walk(item, (*at, i))

    walk(root, ())
    return out, _leg_lines(root)


def _leg_lines(root: Any) -> dict[str, int]:
    """Line (1-based) of each leg's mapping under the composed file's ``root``, by leg name."""
    import yaml

    out: dict[str, int] = {}
    if not isinstance(root, yaml.MappingNode):
        return out
    for key, value in root.value:
        if getattr(key, "value", None) == "legs" and isinstance(value, yaml.SequenceNode):
            for item in value.value:
                if isinstance(item, yaml.MappingNode):
                    for k, v in item.value:
                        if getattr(k, "value", None) == "name" and isinstance(v.value, str):
                            out.setdefault(v.value, item.start_mark.line + 1)
    return out


def _at_line(p: Problem, lines: dict[str, int]) -> Problem:
    if p.leg is None or p.leg not in lines or "(line " in p.detail:
        return p
    return Problem(p.kind, p.leg, p.point, f"{p.detail} (line {lines[p.leg]})")


def _comment_block(source: str) -> str:
    """The comment lines at the top of the file, without their ``#``."""
    out = []
    for line in source.splitlines():
        if not line.startswith("#"):
            break
        out.append(line[1:].strip())
    return "\n".join(out).strip()


def _number(
    value: Any, what: str, found: _Problems, leg: str | None, at: Where | None = None
) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        found.add("bad_value", f"{what} must be a finite number, got {value!r}", leg, at=at)
        return None
    return float(value)


def _vector(
    value: Any, what: str, found: _Problems, leg: str | None, at: Where | None = None
) -> np.ndarray | None:
    ok = (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    )
    if not ok or not all(math.isfinite(v) for v in value):
        found.add(
            "bad_vector",
            f"{what} must be [x, y, z], three finite numbers; got {value!r}",
            leg,
            at=at,
        )
        return None
    return np.array(value, dtype=np.float64)


def _script(script: Any, path: Path, found: _Problems, unwritten: bool) -> dict[str, str]:
    """``graph`` and ``single`` of the ``script`` section, resolved (shipped name or path; a
    missing file only when ``unwritten``)."""
    from langenv.speech.graph import SHIPPED_GRAPHS

    if not isinstance(script, dict):
        found.add("not_mapping", "script must be a mapping with 'graph' and/or 'single'")
        return {}
    for key in sorted(set(script) - _SCRIPT, key=str):
        found.unknown(key, _SCRIPT, ("script",), what="script: ")
    out = {}
    for key in ("graph", "single"):
        if key not in script:
            continue
        ref = script[key]
        if not isinstance(ref, str) or not ref.strip():
            found.add("bad_graph", f"script.{key} must be a graph name or a YAML path")
            continue
        if ref.replace("_", "-") in SHIPPED_GRAPHS:
            out[key] = ref
            continue
        file = (path.parent / ref).resolve()
        if not file.is_file() and not (unwritten and not file.exists()):
            found.add(
                "bad_graph",
                f"script.{key}: {ref!r} is neither a shipped graph ({', '.join(SHIPPED_GRAPHS)}) "
                f"nor a file (looked for {file})",
            )
            continue
        out[key] = str(file)
    return out


def _legs(raw: Any, found: _Problems, lines: dict[str, int], start: np.ndarray | None) -> list[Leg]:
    if not isinstance(raw, list) or not raw:
        found.add("bad_value", "legs must be a non-empty list of legs")
        return []
    legs = []
    for i, item in enumerate(raw):
        before = len(found)
        leg = _leg(item, i, found, start)
        for j in range(before, len(found)):
            found[j] = _at_line(found[j], lines)
        if leg is not None:
            legs.append(leg)
    return legs


def _leg(item: Any, i: int, found: _Problems, start: np.ndarray | None) -> Leg | None:
    if not isinstance(item, dict):
        found.add("not_mapping", f"legs[{i}] must be a mapping (name and one of line, arc, spline)")
        return None
    name = item.get("name")
    if not isinstance(name, str) or not name.strip():
        found.add("missing_key", f"legs[{i}] needs a 'name' (a non-empty string)")
        name = f"#{i}"
    n_before = len(found)
    at: Where = ("legs", i)
    for key in sorted(set(item) - _LEG, key=str):
        found.unknown(key, _LEG, at, name)
    kinds = [k for k in LEG_KINDS if k in item]
    if len(kinds) != 1:
        found.add(
            "leg_kind", f"a leg is exactly one of line, arc, spline; got {kinds or 'none'}", name
        )
        return None
    kind = kinds[0]
    body = item[kind]
    if not isinstance(body, dict):
        found.add(
            "not_mapping", f"{kind} must be a mapping of {', '.join(sorted(_FIELDS[kind]))}", name
        )
        return None
    for key in sorted(set(body) - _FIELDS[kind], key=str):
        found.unknown(key, _FIELDS[kind], (*at, kind), name, what=f"{kind}: ")
    args: dict[str, Any] = {"name": name, "kind": kind}
    if kind == "line":
        args.update(_line(body, name, found, (*at, kind)))
    elif kind == "arc":
        args.update(_arc(body, name, found, (*at, kind)))
    else:
        args.update(_spline(body, name, found, (*at, kind)))
    args.update(_tool(item.get("tool"), name, found, (*at, "tool")))
    if "waypoint" in item:
        args["waypoint"] = _vector(item["waypoint"], "waypoint (m)", found, name, (*at, "waypoint"))
    if len(found) > n_before:
        return None
    if isinstance(args.get("end"), str):  # line.to: start
        if start is None:
            return None  # the missing start is reported already
        args["end"] = start
    try:
        return Leg(**args)
    except ExerciseError as exc:
        found.extend(exc.problems)
        return None


def _line(body: dict[str, Any], name: str, found: _Problems, at: Where) -> dict[str, Any]:
    if "to" not in body:
        found.add("missing_key", "line needs 'to': [x, y, z] or 'start'", name, at=at)
        return {}
    if body["to"] == "start":
        return {"end": "start"}
    end = _vector(body["to"], "line.to (m)", found, name, (*at, "to"))
    return {} if end is None else {"end": end}


def _arc(body: dict[str, Any], name: str, found: _Problems, at: Where) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key in ("center", "axis", "angle"):
        if key not in body:
            found.add("missing_key", f"arc needs {key!r}", name, at=at)
    if "center" in body:
        out["center"] = _vector(body["center"], "arc.center (m)", found, name, (*at, "center"))
    if "axis" in body:
        axis = _vector(body["axis"], "arc.axis", found, name, (*at, "axis"))
        if axis is not None and float(np.linalg.norm(axis)) < 1e-9:
            found.add("degenerate", "arc.axis must be non-zero", name, at=(*at, "axis"))
        out["axis"] = axis
    if "angle" in body:
        rule = "satisfy 0 < |angle| <= 360"
        angle = _degrees(
            body, "angle", "arc.angle", (rule, lambda v: 0.0 < abs(v) <= 360.0), found, name, at
        )
        if angle is not None:
            out["angle"] = angle
    return out


def _spline(body: dict[str, Any], name: str, found: _Problems, at: Where) -> dict[str, Any]:
    out: dict[str, Any] = {}
    pts = body.get("through")
    if not isinstance(pts, list) or not pts:
        found.add("missing_key", "spline needs 'through': a list of [x, y, z] points", name, at=at)
    else:
        good = []
        for j, p in enumerate(pts):
            before = len(found)
            v = _vector(p, f"spline.through[{j}] (m)", found, name, (*at, "through", j))
            if v is None:
                found[before] = Problem("bad_vector", name, j, found[before].detail)
            else:
                good.append(v)
        out["through"] = np.array(good)
    if "tolerance" in body:
        tol = _number(body["tolerance"], "spline.tolerance (m)", found, name, (*at, "tolerance"))
        if tol is not None:
            out["tolerance"] = tol
    return out


def _degrees(
    body: dict[str, Any],
    key: str,
    what: str,
    rule: tuple[str, Callable[[float], bool]],
    found: _Problems,
    name: str,
    at: Where,
) -> float | None:
    """``body[key]``, an angle in degrees (``what`` names it), in radians; None with a
    ``bad_value`` problem when it does not hold ``rule`` (what it must do, and the test)."""
    value = _number(body[key], f"{what} (deg)", found, name, (*at, key))
    if value is None:
        return None
    if not rule[1](value):
        found.add("bad_value", f"{what} must {rule[0]} deg, got {value}", name, at=(*at, key))
        return None
    return math.radians(value)


def _tool(raw: Any, name: str, found: _Problems, at: Where) -> dict[str, Any]:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        found.add("not_mapping", "tool must be a mapping {turn: deg, axis: [x, y, z]}", name, at=at)
        return {}
    for key in sorted(set(raw) - _TOOL, key=str):
        found.unknown(key, _TOOL, at, name, what="tool: ")
    out: dict[str, Any] = {}
    if "turn" in raw:
        rule = "lie in [-360, 360]"
        turn = _degrees(
            raw, "turn", "tool.turn", (rule, lambda v: abs(v) <= 360.0), found, name, at
        )
        if turn is not None:
            out["tool_turn"] = turn
    if "axis" in raw:
        axis = _vector(raw["axis"], "tool.axis", found, name, (*at, "axis"))
        if axis is not None and float(np.linalg.norm(axis)) < 1e-9:
            found.add("degenerate", "tool.axis must be non-zero", name, at=(*at, "axis"))
        elif axis is not None:
            out["tool_axis"] = axis
    return out
