"""What every session of a process shares: one clip library per TTS cache and one phrase graph
per graph file and library, loaded once.

A batch of sessions (:mod:`langenv.batch`) speaks the same graph N times: each session used to
load it again, with a clip library of its own that held every clip's audio. Here the first
session loads it (:meth:`PhraseGraph.load <langenv.speech.graph.PhraseGraph.load>`) and the
others get that object: a graph does not change once built (its tables are read-only
mappings), and each session's state lives in its own :class:`~langenv.speech.timeline.
SpeechTimeline`. A graph needs its clips' lengths, not their sound
(:meth:`ClipLibrary.samples <langenv.speech.audio.ClipLibrary.samples>`): the audio is loaded
only where it is rendered, by :meth:`ClipLibrary.clip <langenv.speech.audio.ClipLibrary.clip>`.
"""

from __future__ import annotations

import hashlib
import threading
import weakref
from pathlib import Path

from langenv.speech.audio import ClipLibrary, default_cache_dir
from langenv.speech.graph import PhraseGraph

__all__ = ["shared_clips", "shared_graph"]

_LOCK = threading.Lock()
_LIBRARIES: dict[Path, ClipLibrary] = {}
_Stamp = tuple[tuple[str, int, int], ...] | None
_GRAPHS: weakref.WeakKeyDictionary[ClipLibrary, dict[tuple[str, str], tuple[PhraseGraph, _Stamp]]]
_GRAPHS = weakref.WeakKeyDictionary()


def shared_clips() -> ClipLibrary:
    """The process's default :class:`ClipLibrary` (default settings), one per TTS cache
    directory (``$LANGCTRL_CACHE`` is read at each call)."""
    where = default_cache_dir()
    with _LOCK:
        clips = _LIBRARIES.get(where)
        if clips is None:
            clips = _LIBRARIES[where] = ClipLibrary(cache_dir=where)
        return clips


def shared_graph(path: str | Path, clips: ClipLibrary | None = None) -> PhraseGraph:
    """``PhraseGraph.load(path, clips)``, loaded once per file content and clip library.

    The graph is keyed by ``path`` as given, the SHA-256 of the file's bytes and ``clips`` (the
    object: a library given by a caller shares its graphs with the sessions given the same
    one); a recorded clip's file that changed since (time or size) loads the graph again.

    Args:
        path: The graph's YAML file.
        clips: Where phrase audio comes from; None: :func:`shared_clips`.

    Raises:
        PhraseGraphError: as :meth:`PhraseGraph.load`.
    """
    clips = clips if clips is not None else shared_clips()
    path = Path(path)
    try:
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return PhraseGraph.load(path, clips)  # its error names the file
    key = (str(path), digest)
    with _LOCK:
        graphs = _GRAPHS.setdefault(clips, {})
        hit = graphs.get(key)
    if hit is not None and hit[1] is not None and hit[1] == _audio_stamp(hit[0]):
        return hit[0]
    graph = PhraseGraph.load(path, clips)
    with _LOCK:
        graphs[key] = (graph, _audio_stamp(graph))
    return graph


def _audio_stamp(graph: PhraseGraph) -> _Stamp:
    """Path, time and size of each recorded clip's file of ``graph``; None if one is gone."""
    stamp = []
    for phrase in graph.source_phrases.values():
        if phrase.audio is not None:
            try:
                st = phrase.audio.stat()
            except OSError:
                return None
            stamp.append((str(phrase.audio), st.st_mtime_ns, st.st_size))
    return tuple(stamp)
