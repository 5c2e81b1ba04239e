"""What a step's ``info`` says (the env's docstring lists its keys): the env's state read into
a dict, the same in every step (the rewards' terms are added by the step)."""

from __future__ import annotations

from typing import Any

__all__ = ["step_info"]


def step_info(env: Any) -> dict[str, Any]:
    """The info of ``env`` (a :class:`~langenv.env.LangCtrlEnv`; typed ``Any``: the env
    imports this module) after its latest tick: times, paces, the person, the speech, the
    alignment and the safety layer's verdict."""
    m = env.motion
    stop = m.safety_stop
    return {
        "time": env.time,
        "t_x": env.t_h,
        "t_a": env.t_a,
        "em": env.t_a - env.t_h,
        "p": env.paces.p,
        "a": env.paces.a,
        "cooperation": m.cooperation,
        "hand_speed": m.hand_speed,
        "progress": m.progress,
        "leg": m.state.leg,
        "phrase": env.speech.phrase,
        "in_pause": env.speech.in_pause,
        "motion_done": m.motion_done,
        "speech_done": env.speech.done,
        "t_motion": m.t_motion_end,
        "t_speech": env.t_speech_end,
        "am": env.am if env.terminated and stop is None else None,
        "path_deviation": m.path_deviation,
        "max_hand_speed": env.max_speed,
        "safety_stop": stop.limit if stop is not None else None,
        "safety_message": stop.message if stop is not None else "",
    }
