"""What a wording asks of the person: the intents a script may mark its wordings with.

A wording may carry one *intent* from :data:`INTENTS`, written after it in a script
(``[Keep going.]<encourage> | [Relax your arm.]<relax>``, :mod:`langenv.speech.author`) and kept
in the graph's YAML (``intent: encourage`` on the vertex). The speech says it as any other
wording; a person who listens (:class:`~langenv.users.listening.ListeningUser`) responds to it
once its last word is heard. A wording without a mark asks nothing in particular
(:meth:`PhraseGraph.intent <langenv.speech.graph.PhraseGraph.intent>` is None).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

__all__ = ["INTENTS", "intent_problem"]

INTENTS: Mapping[str, str] = MappingProxyType(
    {
        "guide": "says where the hand goes next (the leg's direction): 'Move your arm back.'",
        "encourage": "keeps the person going: 'Keep going.', 'You're doing really well.'",
        "relax": "asks the person to stop pushing against the arm: 'Relax your arm.'",
        "faster": "asks for more speed: 'A bit quicker now.'",
        "slower": "asks for less speed: 'Nice and slow.'",
    }
)
"""The intents a wording may carry, by name, with what each asks of the person (the one place
the names live: the script parser, the graph loader and the listening person read it)."""


def intent_problem(name: object) -> str:
    """Why ``name`` is not an intent of :data:`INTENTS` ('' when it is)."""
    if isinstance(name, str) and name in INTENTS:
        return ""
    return f"unknown intent {name!r}; known: {', '.join(INTENTS)}"
