"""One session voiced both ways: the figure of ``docs/speech.md`` (``docs/natural_voice.png``).

Run::

    langctrl compare --policies lc --users synthetic:12 --seed 0 --out out/main
    langctrl voice-figure out/main/sessions/lc_s3.npz --out natural_voice.png

The top panel shows the session's speech pace ``a`` and the person's cooperation ``c``; below,
the speech rendered with the paper's stretched voice and with the natural voice
(:mod:`langenv.speech.voice`), each clip's slot in the timeline shaded.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from eval.episode import EpisodeLog
from eval.video import session_audio

__all__ = ["voice_figure"]


def voice_figure(log: EpisodeLog, out: Path) -> Path:
    """Write the figure of ``log`` (a session of a phrase-choosing policy) to ``out`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(3, 1, figsize=(10, 5.5), sharex=True)
    ax[0].plot(log.t, log.a, lw=1, label="speech pace a")
    ax[0].plot(log.t, log.cooperation, lw=1, label="cooperation c")
    ax[0].axhspan(0.9, 1.1, color="g", alpha=0.1)
    ax[0].legend(loc="lower right", fontsize=8)
    ax[0].set_ylabel("pace")
    for k, voice in enumerate(("stretch", "natural")):
        y, sr = session_audio(dataclasses.replace(log, voice=voice))
        ax[k + 1].plot(np.arange(y.size) / sr, y, lw=0.3, color="k")
        ax[k + 1].set_ylabel(f"{voice} voice")
        for u in log.utterances:
            if not u.is_pause:
                ax[k + 1].axvspan(u.t_start, u.t_end, color="C0", alpha=0.08)
    ax[2].set_xlabel("time (s)")
    ax[0].set_title(
        f"{log.policy}, {log.user}: the same session voiced two ways "
        "(shaded: each clip's slot in the timeline)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
