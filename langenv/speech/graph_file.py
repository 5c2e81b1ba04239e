"""The phrase graph's file (SPEC §4): a YAML document read and checked into its parts, every
problem at once, each naming the file and the vertex (:meth:`PhraseGraph.load
<langenv.speech.graph.PhraseGraph.load>` measures the clips and builds the graph)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from langenv.errors import PhraseGraphError
from langenv.speech.graph_checks import GraphParts, structure_problems, unreachable_problems
from langenv.speech.intents import intent_problem
from langenv.speech.phrase import DEFAULT_PAUSE, MAX_PAUSE, Phrase, bounds_problem, is_number
from langenv.speech.repeat import parse_repeats
from langenv.speech.voice import VOICES

__all__ = ["GraphFile", "read_graph_file"]

_TOP_KEYS = frozenset({"start", "pause", "phrases", "voice", "repeats", "final_wait", "legs"})
_PHRASE_KEYS = frozenset({"text", "audio", "next", "filler", "pause", "leg", "intent"})


@dataclass(frozen=True)
class GraphFile:
    """A phrase graph file's content, checked: its vertices, where the speech starts, and the
    rest of the graph's parts."""

    path: Path
    phrases: dict[str, Phrase]
    start: str
    parts: GraphParts


def read_graph_file(path: str | Path) -> GraphFile:
    """Read and check a phrase graph file, all but its clips.

    Raises:
        PhraseGraphError: listing every problem found, one per line, each naming the file and
            (where it applies) the vertex: unreadable file, bad YAML, unknown keys, bad
            ``pause``, unknown ``start``/``next`` ids, a phrase or filler with neither ``text``
            nor ``audio``, bad pause bounds, a cycle, a vertex that cannot reach a terminal or
            that ``start`` never reaches, a misplaced pause, bad repeats, legs or intents.
    """
    path = Path(path)
    try:
        source = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or exc
        raise PhraseGraphError(f"{path}: cannot read phrase graph: {reason}") from None
    import yaml

    from langenv.validation import yaml_text

    try:
        data = yaml.safe_load(yaml_text(source, path))
    except yaml.YAMLError as exc:
        raise PhraseGraphError(f"{path}: invalid YAML: {exc}") from None
    start, pause, voice, phrases = _parse(path, data)
    assert isinstance(data, dict)
    repeats, problems = parse_repeats(path, data.get("repeats"))
    legs, leg_of = _parse_legs(path, data, problems)
    intents = _parse_intents(path, data, problems)
    final_wait = data.get("final_wait", False)
    if not isinstance(final_wait, bool):
        problems.append(f"{path}: 'final_wait' must be true or false, got {final_wait!r}")
    if problems:
        raise PhraseGraphError("\n".join(problems))
    problems = structure_problems(str(path), phrases, start)
    if not problems:
        problems = unreachable_problems(str(path), phrases, start)
    if problems:
        raise PhraseGraphError("\n".join(problems))
    parts = GraphParts(pause, voice, repeats, final_wait, legs, leg_of, intents)
    return GraphFile(path, phrases, start, parts)


def _parse(path: Path, data: object) -> tuple[str, float, str, dict[str, Phrase]]:
    """Check the YAML document's shape; build the phrases (all problems at once)."""
    if not isinstance(data, dict):
        kind = "empty" if data is None else f"a {type(data).__name__}"
        raise PhraseGraphError(
            f"{path}: a phrase graph must be a mapping with 'start' and "
            f"'phrases', the file is {kind}"
        )
    problems: list[str] = []
    unknown = sorted(str(k) for k in data if k not in _TOP_KEYS)
    if unknown:
        problems.append(f"{path}: unknown key(s) {unknown}; allowed: {sorted(_TOP_KEYS)}")
    start = data.get("start")
    if not isinstance(start, str) or not start:
        problems.append(f"{path}: 'start' must be a phrase id, got {start!r}")
    pause = data.get("pause", DEFAULT_PAUSE)
    if not is_number(pause) or not 0.0 <= float(pause) <= MAX_PAUSE:
        problems.append(
            f"{path}: 'pause' must be a number of seconds in [0, {MAX_PAUSE}], got {pause!r}"
        )
    voice = data.get("voice", "stretch")
    if voice not in VOICES:
        problems.append(f"{path}: 'voice' must be one of {list(VOICES)}, got {voice!r}")
    raw = data.get("phrases")
    phrases: dict[str, Phrase] = {}
    if not isinstance(raw, dict) or not raw:
        problems.append(f"{path}: 'phrases' must be a non-empty mapping of phrase id -> phrase")
        raw = {}
    for pid, spec in raw.items():
        if not isinstance(pid, str) or not pid:
            problems.append(f"{path}: phrase id {pid!r} must be a non-empty string (quote it)")
            continue
        ph, found = _parse_vertex(path, pid, spec)
        problems += found
        if ph is not None:
            phrases[pid] = ph
    if problems:
        raise PhraseGraphError("\n".join(problems))
    assert isinstance(start, str)
    return start, float(pause), str(voice), phrases


def _parse_legs(
    path: Path, data: dict[str, Any], problems: list[str]
) -> tuple[tuple[str, ...], dict[str, str]]:
    """The file's ``legs`` and each vertex's ``leg`` (problems appended, naming the file)."""
    raw = data.get("legs", [])
    if not isinstance(raw, list) or not all(isinstance(x, str) and x for x in raw):
        problems.append(f"{path}: 'legs' must be a list of leg names, got {raw!r}")
        raw = []
    leg_of: dict[str, str] = {}
    for pid, spec in (data.get("phrases") or {}).items():
        if isinstance(spec, dict) and "leg" in spec:
            leg = spec["leg"]
            if not isinstance(leg, str) or not leg:
                problems.append(f"{path}: vertex {pid!r}: 'leg' must be a leg name, got {leg!r}")
                continue
            leg_of[str(pid)] = leg
    return tuple(raw), leg_of


def _parse_intents(path: Path, data: dict[str, Any], problems: list[str]) -> dict[str, str]:
    """Each vertex's ``intent`` (problems appended, naming the file and the vertex)."""
    intents: dict[str, str] = {}
    for pid, spec in (data.get("phrases") or {}).items():
        if isinstance(spec, dict) and "intent" in spec:
            found = intent_problem(spec["intent"])
            if found:
                problems.append(f"{path}: vertex {pid!r}: {found}")
                continue
            intents[str(pid)] = spec["intent"]
    return intents


def _parse_vertex(path: Path, pid: str, spec: object) -> tuple[Phrase | None, list[str]]:
    """One vertex of the YAML (phrase, filler or pause) and the problems found in it."""
    if not isinstance(spec, dict):
        return None, [
            f"{path}: phrase {pid!r}: must be a mapping with 'text' and/or 'audio' (or 'pause') "
            "and 'next'"
        ]
    is_pause = "pause" in spec
    filler = spec.get("filler", False)
    kind = "pause" if is_pause else ("filler" if filler is True else "phrase")
    where = f"{path}: {kind} {pid!r}"
    problems: list[str] = []
    bad = sorted(str(k) for k in spec if k not in _PHRASE_KEYS)
    if bad:
        problems.append(f"{where}: unknown key(s) {bad}; allowed: {sorted(_PHRASE_KEYS)}")
    if not isinstance(filler, bool):
        problems.append(f"{where}: 'filler' must be true or false, got {filler!r}")
    text = spec.get("text")
    audio = spec.get("audio")
    bounds = None
    if is_pause:
        for key in ("text", "audio", "filler"):
            if key in spec:
                problems.append(f"{where}: a pause is silence: it has no {key!r}")
        found = bounds_problem(spec["pause"])
        if found:
            problems.append(f"{where}: {found}")
        else:
            bounds = (float(spec["pause"][0]), float(spec["pause"][1]))
    else:
        if text is not None and (not isinstance(text, str) or not text.strip()):
            problems.append(f"{where}: 'text' must be a non-empty string, got {text!r}")
        if audio is not None and (not isinstance(audio, str) or not audio.strip()):
            problems.append(f"{where}: 'audio' must be a file path, got {audio!r}")
        if text is None and audio is None:
            problems.append(
                f"{where}: no audio: give 'text' (spoken by TTS) or 'audio'"
                if kind == "filler"
                else f"{where}: has neither 'text' nor 'audio'"
            )
    if "next" not in spec:
        problems.append(f"{where}: missing 'next' (write next: [] for a final phrase)")
    nxt = spec.get("next")
    nxt = [] if nxt is None else [nxt] if isinstance(nxt, str) else nxt
    if not isinstance(nxt, list) or not all(isinstance(v, str) and v for v in nxt):
        problems.append(f"{where}: 'next' must be a list of phrase ids, got {spec.get('next')!r}")
    if problems:
        return None, problems
    audio_path = None if audio is None else (path.parent / Path(audio).expanduser())
    return (
        Phrase(
            id=pid,
            text=None if is_pause else text,
            audio=None if is_pause else audio_path,
            next=tuple(nxt),
            kind=kind,
            bounds=bounds,
        ),
        [],
    )
