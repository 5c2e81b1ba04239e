"""Live mode: the real-time loop headless, its audio stream, the ring, the drag user, the policy
registry and the clear errors of ``langctrl play``."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import soundfile as sf

import langenv
from langctrl.jobs.play import main, parse_args
from langenv.errors import ConfigError, DeviceError
from langenv.live.drag import DragUser
from langenv.live.loop import RealTimeLoop
from langenv.live.registry import POLICY_GROUP, load_registered_policy, registered_policies
from langenv.live.ring import AudioRing
from langenv.live.sinks import SoundCardSink, WavSink
from langenv.live.stream import DEFAULT_LAG
from langenv.speech.render import render_history

ROOT = Path(__file__).resolve().parents[1]
SECONDS = 3.0


def test_the_policies_package_registers_its_policies() -> None:
    found = registered_policies()
    missing = {"ac", "lc-noap", "lc", "lc-em", "lc-end", "lc-em-end", "ppo"} - set(found)
    assert not missing, (
        f"entry points {sorted(missing)} of group {POLICY_GROUP!r} are not installed: run the "
        "README's pip install line again"
    )
    policy = load_registered_policy("lc")
    assert policy.name == "lc" and policy.decision_hz == 500


def test_unknown_or_broken_policy_is_a_clear_error() -> None:
    with pytest.raises(ConfigError, match=r"telepathy.*registered: .*lc"):
        load_registered_policy("telepathy")
    with pytest.raises(ConfigError, match=r"nothing\.zip"):
        load_registered_policy("ppo:/no/such/nothing.zip")


def test_live_mode_imports_no_policy_training_or_eval_code() -> None:
    """The live mode finds policies through entry points, never by importing them."""
    play = ROOT / "langctrl" / "jobs" / "play.py"
    for path in [*(ROOT / "langenv" / "live").rglob("*.py"), play]:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                names = [node.module]
            for name in names:
                assert name.split(".")[0] not in ("policies", "train", "eval"), (path, name)


def test_ring_counts_underruns_and_never_overwrites() -> None:
    ring = AudioRing(8)
    assert ring.write(np.arange(6, dtype=np.float32)) == 6
    assert ring.write(np.arange(6, dtype=np.float32)) == 2  # only what fits
    out = np.empty(5, np.float32)
    assert ring.read_into(out) == 5 and out.tolist() == [0, 1, 2, 3, 4]
    out = np.empty(5, np.float32)
    assert ring.read_into(out) == 3 and out.tolist() == [5, 0, 1, 0, 0]
    assert ring.underruns == 1 and ring.missing == 2
    with pytest.raises(ConfigError, match="capacity"):
        AudioRing(0)


def test_drag_user_is_a_capped_spring_from_the_grabbed_point_to_the_mouse() -> None:
    class Perturb:
        select, active = 1, 1
        localpos = np.zeros(3)
        refselpos = np.array([0.1, 0.0, 0.0])

    class Data:
        xpos = np.zeros((2, 3))
        xmat = np.tile(np.eye(3).ravel(), (2, 1))
        xfrc_applied = np.ones((2, 6))

    user, data = DragUser(stiffness=300.0, max_force=60.0), Data()
    user.update(Perturb(), data)
    np.testing.assert_allclose(user.force(0.0, np.zeros(3), np.ones(3)), [30.0, 0.0, 0.0])
    assert not data.xfrc_applied.any()  # the viewer's own push is cleared
    Perturb.refselpos = np.array([0.0, 1.0, 0.0])
    user.update(Perturb(), data)
    np.testing.assert_allclose(user.current, [0.0, 60.0, 0.0])  # capped
    Perturb.active = 2  # a rotation drag is no push
    user.update(Perturb(), data)
    assert not user.current.any()


def test_headless_loop_keeps_real_time_and_streams_the_offline_rendering(tmp_path: Path) -> None:
    """A short real-time session: every tick run, the audio written at the sound card's pace is
    sample for sample the offline rendering (render_history) of the session's own pace trace."""
    from policies.analytic import make_analytic

    # LC deciding at 25 Hz: the loop's cost per tick is small, so a loaded machine still keeps up
    policy = make_analytic("lc", decision_hz=25)
    env = gym.make(langenv.ENV_ID, phrase_graph="lc", decision_hz=25)
    wav = tmp_path / "live.wav"
    # a half-second buffer: a loaded test machine must not turn this into a test of its load
    loop = RealTimeLoop(env, policy, lambda ring, sr: WavSink(ring, wav, sr), prefill=0.5)
    report = loop.run(SECONDS)
    base = env.unwrapped
    assert report.ticks == round(SECONDS * 500) and report.sim_s == pytest.approx(SECONDS)
    # its pace against the wall clock is a figure of the benchmarks (bench: live_wall_over_sim)
    assert report.late_ticks >= 0 and "late ticks" in report.summary()
    assert report.underruns == 0 and report.starved == 0
    live, sr = sf.read(wav, dtype="float32")
    assert sr == base.clips.sr
    assert live.size / sr == pytest.approx(SECONDS - DEFAULT_LAG, abs=0.05)
    t, a = loop.stream.trace()
    assert a.min() < 0.95  # LC changed the audio pace while it spoke (the user resisted)
    offline = render_history(
        base.graph, base.clips, base.speech.path, t, a, pause_lengths=base.speech.pause_lengths
    )
    n = live.size
    assert np.abs(live).max() > 0.05
    np.testing.assert_allclose(live, offline[:n], atol=2.0 / 32768)  # 16-bit PCM
    env.close()


def test_live_mode_says_repeats_and_waits_as_the_offline_rendering_does(tmp_path: Path) -> None:
    """A graph whose repeat starts at once and whose last phrase waits: the live stream says the
    sayings and the silences of the wait sample for sample as the offline rendering."""
    from langenv.speech.author import author
    from policies.analytic import make_analytic

    script = tmp_path / "s.txt"
    script.write_text(
        "@voice natural\n@pause 0.2\nGo.\nKeep going. (repeat 4, gap 0.2-0.4)\nDone.\n"
    )
    graph = author(script, tmp_path / "s.yaml")
    policy = make_analytic("lc", decision_hz=25)
    env = gym.make(langenv.ENV_ID, phrase_graph=str(graph.path), decision_hz=25)
    wav = tmp_path / "live.wav"
    loop = RealTimeLoop(env, policy, lambda ring, sr: WavSink(ring, wav, sr), prefill=0.5)
    report = loop.run(SECONDS + 1.0)
    assert report.underruns == 0 and report.starved == 0
    base = env.unwrapped
    said = base.speech.path  # type: ignore[attr-defined]
    assert "keep_going#2" in said and "again_4#gap1" in said  # a repeat, said live
    live, _sr = sf.read(wav, dtype="float32")
    t, a = loop.stream.trace()
    offline = render_history(
        base.graph,
        base.clips,
        said,
        t,
        a,
        pause_lengths=base.speech.pause_lengths,  # type: ignore[attr-defined]
    )
    np.testing.assert_allclose(live, offline[: live.size], atol=2.0 / 32768)
    env.close()


def test_play_headless_prints_one_summary_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    wav = tmp_path / "x.wav"
    args = ["--headless", "--seconds", "1", "--audio-out", str(wav), "--policy", "ac"]
    assert main(args) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and "late ticks" in out[0] and "audio underruns" in out[0]
    assert str(wav) in out[0] and wav.stat().st_size > 1000


def test_play_errors_are_clear(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(SystemExit):
        parse_args(["--headless", "--seconds", "1"])  # no --audio-out
    assert "--audio-out" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        parse_args(["--headless", "--seconds", "1", "--audio-out", "x.wav", "--user", "drag"])
    args = ["--headless", "--seconds", "1", "--audio-out", str(tmp_path / "x.wav")]
    assert main([*args, "--policy", "telepathy"]) == 2
    assert "telepathy" in capsys.readouterr().err
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if sys.platform.startswith("linux"):
        assert main(["--seconds", "1"]) == 2
        err = capsys.readouterr().err
        assert "no display" in err and "--headless" in err and "Traceback" not in err


def test_no_sound_library_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "sounddevice", None)  # import fails as when not installed
    with pytest.raises(DeviceError, match="--audio-out"):
        SoundCardSink(AudioRing(1024), 22050)


def test_missing_portaudio_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """sounddevice raises OSError at import when the system PortAudio library is absent."""
    import builtins

    real_import = builtins.__import__

    def fake_import(name: str, *args: object, **kwargs: object) -> object:
        if name == "sounddevice":
            raise OSError("PortAudio library not found")
        return real_import(name, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.delitem(sys.modules, "sounddevice", raising=False)
    monkeypatch.setattr(builtins, "__import__", fake_import)
    with pytest.raises(DeviceError, match="libportaudio2"):
        SoundCardSink(AudioRing(1024), 22050)


def test_play_refuses_to_replace_an_output_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """As every other job: an existing --audio-out (or --trace-out) is kept unless --overwrite."""
    wav = tmp_path / "live.wav"
    wav.write_bytes(b"RIFF the last session")
    args = ["--headless", "--seconds", "1", "--audio-out", str(wav)]
    with pytest.raises(SystemExit) as info:
        parse_args(args)
    assert info.value.code == 2
    assert f"--audio-out {wav}: exists; give --overwrite to replace it" in capsys.readouterr().err
    assert wav.read_bytes() == b"RIFF the last session"
    assert parse_args([*args, "--overwrite"]).overwrite
