"""Every tool takes the exercise: eval.compare, play, train.ppo; headless MuJoCo by default."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from eval.compare import main as compare
from eval.episode import EpisodeLog
from langctrl.jobs.play import main as play
from langenv.exercise import resolve_exercise

REPO = Path(__file__).resolve().parents[1]


def test_compare_runs_an_exercise_with_its_script(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cmp"
    args = ["--exercise", "forearm_rotation", "--policies", "ac,lc", "--users", "synthetic:1"]
    assert compare([*args, "--out", str(out), "--workers", "1", "--decision-hz", "50"]) == 0
    rows = list(csv.DictReader((out / "sessions.csv").open()))
    assert [r["policy"] for r in rows] == ["ac", "lc"]
    ac_log = EpisodeLog.load_npz(out / "sessions" / "ac_s0.npz")
    assert ac_log.phrase_graph.endswith("forearm_rotation_single.yaml")
    for r in rows:
        assert r["protective_stop"] == "0.0" and r["truncated"] == "0.0"
        assert np.isfinite(float(r["am"]))
    log = EpisodeLog.load_npz(out / "sessions" / "lc_s0.npz")
    ex = resolve_exercise("forearm_rotation")
    assert log.path is not None
    np.testing.assert_allclose(log.path, ex.trajectory.sample(200), atol=1e-6)  # float32
    assert log.phrase_graph.endswith("forearm_rotation_lc.yaml")  # the exercise's script
    assert (out / "sessions" / "lc_s0.wav").stat().st_size > 10_000
    assert '"exercise": "forearm_rotation"' in (out / "config.json").read_text()
    capsys.readouterr()


def test_compare_refuses_an_unsafe_exercise_before_any_episode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "far.yaml"
    bad.write_text(
        "name: far\ntitle: Far\nstart: [-0.35, -0.55, 0.06]\nswitch_tol: 0.035\nlegs:\n"
        "  - name: reach\n    line: {to: [-0.35, -1.3, 0.06]}\n"
    )
    out = tmp_path / "cmp"
    assert compare(["--exercise", str(bad), "--users", "synthetic:1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--exercise" in err and "leg 'reach'" in err and "unreachable" in err
    assert not out.exists()


def test_play_headless_on_an_exercise(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    wav = tmp_path / "x.wav"
    args = ["--headless", "--seconds", "1", "--audio-out", str(wav), "--policy", "lc"]
    assert play([*args, "--exercise", "shoulder_abduction"]) == 0
    assert "late ticks" in capsys.readouterr().out and wav.stat().st_size > 1000
    assert play([*args, "--overwrite", "--exercise", "no_such_exercise"]) == 2
    assert "no_such_exercise" in capsys.readouterr().err


@pytest.mark.slow
def test_train_ppo_takes_a_list_of_exercises(tmp_path: Path) -> None:
    config = tmp_path / "two.yaml"
    config.write_text(
        f"inherit: {REPO / 'configs' / 'ppo.yaml'}\n"
        "LangCtrl-v0:\n"
        "  n_steps: 128\n"
        "  batch_size: 64\n"
        "  env_kwargs:\n"
        "    exercise: [external_rotation, hand_to_mouth]\n"
    )
    env = dict(os.environ, PYTHONPATH=str(REPO))
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "train.ppo", "--config", str(config), "--no-progress-bar"]
    cmd += ["--out", str(out), "--n-envs", "2", "--total-timesteps", "256"]
    cmd += ["--n-eval-episodes", "0", "--vec-env", "dummy"]
    res = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    saved = yaml.safe_load((out / "run_config.yaml").read_text())
    assert "hand_to_mouth" in str(saved)


def test_train_ppo_gives_env_i_exercise_i_mod_k() -> None:
    from train.factories import exercise_kwargs

    kws = exercise_kwargs({"decision_hz": 25, "exercise": ["external_rotation", "hand_to_mouth"]})
    assert [k["exercise"] for k in kws] == ["external_rotation", "hand_to_mouth"]
    assert all(k["decision_hz"] == 25 for k in kws)
    assert exercise_kwargs({"decision_hz": 25}) == [{"decision_hz": 25}]


def test_headless_rendering_needs_no_mujoco_gl_whatever_the_import_order() -> None:
    probe = (
        "import gymnasium as gym, langenv\n"
        "env = gym.make('LangCtrl-v0', render_mode='rgb_array'); env.reset(seed=0)\n"
        "print(env.render().shape)\n"
    )
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("MUJOCO_GL", "DISPLAY", "PYOPENGL_PLATFORM")
    }
    env["PYTHONPATH"] = str(REPO)
    empty = "import mujoco\nmujoco.Renderer(mujoco.MjModel.from_xml_string('<mujoco/>'), 8, 8)\n"
    egl = {**env, "MUJOCO_GL": "egl"}
    control = subprocess.run([sys.executable, "-c", empty], env=egl, capture_output=True, text=True)
    if control.returncode != 0:  # the capability, probed on an empty model: not our renderer
        pytest.skip(f"no EGL on this machine: {control.stderr.strip().splitlines()[-1:]}")
    for first in ("", "import mujoco\n"):  # langenv first, and MuJoCo imported before it
        res = subprocess.run(
            [sys.executable, "-c", first + probe], env=env, capture_output=True, text=True
        )
        assert res.returncode == 0, res.stderr[-2000:]
        assert "(480, 640, 3)" in res.stdout
