"""The clips of the shipped phrases, pinned: their lengths and sample digests in a committed file.

A phrase's duration decides the speech timeline (``t_a``, every ETC, the observations), so a
change of text-to-speech engine, voice settings or trimming changes every episode. The manifest
(``langenv/assets/tts_manifest.json``) records, for every text of every shipped phrase graph
(``langenv/assets/graphs``) and exercise script (``langenv/assets/exercises/scripts``), the
number of samples of its clip and a SHA-256 of them, with the engine version and voice settings
they were made with; :func:`compare` names every phrase whose clip differs, so such a change
fails loudly (``tests/test_tts_manifest.py``) instead of shifting results quietly.

    langctrl tts-manifest            # compare fresh clips with the manifest
    langctrl tts-manifest --write    # pin the current clips (after a deliberate change)

Both synthesise into an empty temporary cache, so the comparison is with what a new machine
makes, never with clips an old cache holds.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from langenv.speech.audio import ClipLibrary, ESpeakEngine
from langenv.speech.graph import GRAPHS_DIR, PhraseGraph

__all__ = ["MANIFEST_PATH", "build", "compare", "shipped_graph_files", "shipped_texts"]

MANIFEST_PATH = GRAPHS_DIR.parent / "tts_manifest.json"
"""The committed manifest."""
SCRIPTS_DIR = GRAPHS_DIR.parent / "exercises" / "scripts"
"""The shipped exercises' phrase graphs."""


def shipped_graph_files() -> list[Path]:
    """Every shipped phrase graph (YAML), sorted."""
    return sorted([*GRAPHS_DIR.glob("*.yaml"), *SCRIPTS_DIR.glob("*.yaml")])


def shipped_texts(clips: ClipLibrary) -> dict[str, list[str]]:
    """Every synthesised text of the shipped graphs -> where it is said (``file:phrase``).

    Loading a graph synthesises its clips into ``clips``.
    """
    where: dict[str, list[str]] = {}
    for path in shipped_graph_files():
        graph = PhraseGraph.load(path, clips=clips)
        for ph in graph.phrases.values():
            if ph.text is not None and ph.audio is None and not ph.is_pause:
                where.setdefault(ph.text, []).append(f"{path.parent.name}/{path.name}:{ph.id}")
    return dict(sorted(where.items()))


def build(clips: ClipLibrary) -> dict[str, Any]:
    """The manifest of the shipped phrases as ``clips`` says them."""
    texts = shipped_texts(clips)
    entries = {}
    for text in texts:
        y = clips.synthesize(text)
        entries[text] = {"samples": int(y.size), "sha256": hashlib.sha256(y.tobytes()).hexdigest()}
    return {
        "engine": f"espeak-ng {ESpeakEngine.get().version}",
        "voice": clips.voice,
        "rate": clips.rate,
        "pitch": clips.pitch,
        "sr": clips.sr,
        "trim_db": clips.trim_db,
        "clips": entries,
    }


def compare(made: dict[str, Any], pinned: dict[str, Any]) -> list[str]:
    """Every difference between a freshly made manifest and the pinned one, one line each,
    naming the setting or the text (with its samples then and now)."""
    problems = [
        f"{key}: pinned {pinned.get(key)!r}, now {made.get(key)!r}"
        for key in ("engine", "voice", "rate", "pitch", "sr", "trim_db")
        if made.get(key) != pinned.get(key)
    ]
    old, new = pinned.get("clips", {}), made.get("clips", {})
    for text in sorted(set(old) | set(new)):
        a, b = old.get(text), new.get(text)
        if a is None:
            problems.append(f"{text!r}: not pinned ({b['samples']} samples now)")
        elif b is None:
            problems.append(f"{text!r}: pinned but no shipped graph says it")
        elif a != b:
            same = a["samples"] == b["samples"]
            what = "same length, other samples" if same else f"{b['samples']} samples now"
            problems.append(f"{text!r}: pinned {a['samples']} samples, {what}")
    return problems


def load(path: Path = MANIFEST_PATH) -> dict[str, Any]:
    """The pinned manifest."""
    data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    return data
