"""Speech: phrase graphs, phrase audio, the variable-rate phase vocoder and the speech timeline.

* :class:`PhraseGraph` (``graph.py``): the YAML phrase DAG of phrases, fillers and pauses,
  validated, with ``t_min``/``t_max``, the pause rule and the speech ETC ``t_a``;
  :data:`SHIPPED_GRAPHS` names the shipped graphs; the paper's choice rule (``choice.py``);
* :func:`author` (``author.py``): phrase graphs written from plain-text scripts;
  :func:`coverage` (``coverage.py``): the motion durations a graph can end together with;
* :class:`ClipLibrary` (``audio.py``): phrase audio from recorded files or eSpeak NG, cached;
  :func:`shared_graph`, :func:`shared_clips` (``shared.py``): one graph and one library for
  every session of a process;
* :class:`SpeechTimeline` (``timeline.py``): playback position at audio pace ``a``;
* :func:`render_speech`, :func:`render_history` (``render.py``): audio of a session's speech
  through the variable-rate phase vocoder (``vocoder.py``);
* ``langctrl speech check|author|render`` (its command line: ``langctrl/jobs/speech.py``).
"""

from langenv.speech.audio import ClipLibrary
from langenv.speech.author import author, parse_script
from langenv.speech.coverage import coverage
from langenv.speech.graph import SHIPPED_GRAPHS, PhraseGraph, default_graph_path
from langenv.speech.phrase import Phrase
from langenv.speech.render import plan_speech, render_history, render_speech
from langenv.speech.shared import shared_clips, shared_graph
from langenv.speech.timeline import SpeechTimeline, Utterance

__all__ = [
    "SHIPPED_GRAPHS",
    "ClipLibrary",
    "Phrase",
    "PhraseGraph",
    "SpeechTimeline",
    "Utterance",
    "author",
    "coverage",
    "default_graph_path",
    "parse_script",
    "plan_speech",
    "render_history",
    "render_speech",
    "shared_clips",
    "shared_graph",
]
