"""eval.video: a short session video has H.264 video and AAC audio, the session's length, and the
session's speech (the same rendering as its WAV) as its sound track, in sync."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import av
import gymnasium as gym
import numpy as np
import pytest

import langenv
from eval.episode import EpisodeLog, EpisodeRecorder
from langenv.errors import ConfigError
from policies import load_policy

FPS = 10  # fewer frames than the default 25, so the test stays fast on 2 cores
GRAPH = """start: go
pause: 0.3
phrases:
  go:
    text: "Push it out."
    next: [done]
  done:
    text: "Done."
    next: []
"""


def short_session(tmp_path: Path) -> EpisodeLog:
    """A whole LC session of a few seconds (a 5 cm exercise, two phrases), with its scene."""
    from eval.compare import _graph_ref, _with_scene
    from langenv.control.trajectory import LineSegment, Trajectory, default_exercise

    start = default_exercise().position(0.0)
    exercise = Trajectory([LineSegment(start, start + np.array([0.05, 0.0, 0.0]), waypoint=True)])
    graph = tmp_path / "short.yaml"
    graph.write_text(GRAPH)
    policy = load_policy("lc")
    env = gym.make(langenv.ENV_ID, phrase_graph=graph, decision_hz=50, trajectory=exercise)
    obs, info = env.reset(seed=3)
    base = env.unwrapped
    rec = EpisodeRecorder(policy="lc", user="s3")
    rec.append(_with_scene(info, base))
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        rec.append(_with_scene(info, base))
        done = terminated or truncated
    assert terminated
    texts = {u: (ph.text or u) for u, ph in base.graph.phrases.items()}
    log = rec.build(
        0.0,
        texts=texts,
        t_motion=info["t_motion"],
        t_speech=info["t_speech"],
        utterances=base.speech.utterances(),
        phrase_graph=_graph_ref(graph),
        path=exercise.sample(50),
        voice=base.graph.voice,
    )
    env.close()
    return log


def decode(path: Path) -> dict[str, object]:
    """Streams, durations (s) and the decoded mono audio of an MP4."""
    with av.open(str(path)) as box:
        streams = {s.type: s for s in box.streams}
        info: dict[str, object] = {
            "video": streams["video"].codec_context.name,
            "audio": streams["audio"].codec_context.name,
            "pix_fmt": streams["video"].codec_context.pix_fmt,
            "fps": float(streams["video"].average_rate),
            "size": (streams["video"].width, streams["video"].height),
            "v_dur": float(streams["video"].duration * streams["video"].time_base),
            "a_dur": float(streams["audio"].duration * streams["audio"].time_base),
            "sr": streams["audio"].rate,
        }
        chunks = []
        for frame in box.decode(audio=0):
            assert frame.pts is not None and frame.pts >= 0
            chunks.append(frame.to_ndarray().reshape(-1))
        info["pcm"] = np.concatenate(chunks)
    return info


def test_session_video_has_both_streams_in_sync(tmp_path: Path, offscreen_gl: None) -> None:
    from eval.video import FRAME_SIZE, session_audio
    from langctrl.jobs.video import main

    log = short_session(tmp_path)
    session = float(log.t[-1] - log.t[0])
    assert 2.0 < session < 8.0
    npz = log.save_npz(tmp_path / "lc_s3.npz")
    out = tmp_path / "lc_s3.mp4"
    assert main([str(npz), "--out", str(out), "--fps", str(FPS)]) == 0

    wav, sr = session_audio(log)  # what langctrl compare writes as the session's WAV
    got = decode(out)
    assert got["video"] == "h264" and got["audio"] == "aac" and got["pix_fmt"] == "yuv420p"
    assert got["fps"] == FPS and got["size"] == FRAME_SIZE
    assert got["sr"] == sr
    assert abs(float(got["v_dur"]) - session) < 0.5  # type: ignore[arg-type]
    assert abs(float(got["a_dur"]) - session) < 0.5  # type: ignore[arg-type]

    # The sound track is the WAV: AAC is lossy, so compare by correlation, and find no lag.
    pcm = np.asarray(got["pcm"], np.float64)
    ref = np.asarray(wav, np.float64)
    n = min(pcm.size, ref.size)
    assert n > 0.9 * ref.size
    assert np.abs(ref).max() > 0.05  # the robot speaks
    lags = range(-256, 257)
    score = [float(np.dot(ref[256 : n - 256], pcm[256 + k : n - 256 + k])) for k in lags]
    best = list(lags)[int(np.argmax(score))]
    assert abs(best) <= 2  # samples: in sync, to 0.1 ms
    corr = np.corrcoef(ref[:n], pcm[:n])[0, 1]
    assert corr > 0.95
    residual = ref[:n] - pcm[:n]
    snr = 10 * np.log10(np.sum(ref[:n] ** 2) / np.sum(residual**2))
    assert snr > 10.0  # dB


def _plain_log(n: int, **extra: Any) -> EpisodeLog:
    """A 1 s episode log of ``n`` samples: cooperative, at the natural paces, aligned."""
    t = np.linspace(0.0, 1.0, n)
    return EpisodeLog(
        policy="lc",
        user="u1",
        t=t,
        cooperation=np.ones_like(t),
        hand_speed=np.zeros_like(t),
        p=np.ones_like(t),
        a=np.ones_like(t),
        t_x=1.0 - t,
        t_a=1.0 - t,
        em=np.zeros_like(t),
        motion_done=t >= 1.0,
        speech_done=t >= 1.0,
        utterances=(),
        t_motion=1.0,
        t_speech=1.0,
        ret=0.0,
        **extra,
    )


def test_video_of_a_log_without_scene_is_a_clear_error(tmp_path: Path) -> None:
    from langctrl.jobs.video import main

    log = _plain_log(26, phrase_graph="lc")
    npz = log.save_npz(tmp_path / "old.npz")
    assert main([str(npz), "--out", str(tmp_path / "x.mp4")]) == 2
    assert not (tmp_path / "x.mp4").exists()
    assert main([str(npz), "--out", str(tmp_path / "x.avi")]) == 2


def test_log_round_trip_keeps_scene_and_graph(tmp_path: Path) -> None:
    qpos = np.arange(30, dtype=np.float64).reshape(5, 6) / 10
    force = np.tile([1.0, -2.0, 0.5], (5, 1))
    log = _plain_log(5, qpos=qpos, f_user=force, phrase_graph="lc")
    back = EpisodeLog.load_npz(log.save_npz(tmp_path / "x.npz"))
    assert back.has_scene and back.phrase_graph == "lc"
    assert back.qpos is not None and back.f_user is not None
    np.testing.assert_allclose(back.qpos, qpos, rtol=1e-6)
    np.testing.assert_allclose(back.f_user, force)
    with pytest.raises(ConfigError, match="f_user"):
        _plain_log(5, f_user=force[:, :2])
    with pytest.raises(ConfigError, match="qpos"):
        _plain_log(5, qpos=qpos[:4])


def test_default_frame_rate_is_25() -> None:
    from eval.video import DEFAULT_FPS
    from langctrl.jobs.video import build_parser

    assert DEFAULT_FPS == 25
    assert build_parser().parse_args(["x.npz", "--out", "x.mp4"]).fps == 25
