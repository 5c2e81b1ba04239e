"""Speech: phrase graphs, phrase audio, the variable-rate phase vocoder and the speech timeline.

* :class:`PhraseGraph` (``graph.py``): the YAML phrase DAG, validated, with ``t_min``/``t_max``,
  the paper's choice rule and the speech ETC ``t_a``;
* :class:`ClipLibrary` (``audio.py``): phrase audio from recorded files or eSpeak NG, cached;
* :class:`SpeechTimeline` (``timeline.py``): playback position at audio pace ``a``;
* :func:`render_speech`, :func:`render_history` (``render.py``): audio of a session's speech
  through the variable-rate phase vocoder (``vocoder.py``);
* ``python -m langenv.speech check|render`` (``__main__.py``).
"""

from langenv.speech.audio import ClipLibrary
from langenv.speech.graph import Phrase, PhraseGraph, default_graph_path
from langenv.speech.render import plan_speech, render_history, render_speech
from langenv.speech.timeline import SpeechTimeline, Utterance

__all__ = [
    "ClipLibrary",
    "Phrase",
    "PhraseGraph",
    "SpeechTimeline",
    "Utterance",
    "default_graph_path",
    "plan_speech",
    "render_history",
    "render_speech",
]
