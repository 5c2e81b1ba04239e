"""The exercise as the env's choice: name, path or object; the study's exactly; any shipped one."""

from __future__ import annotations

import hashlib
import math
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import langenv
from langenv.control.cooperation import CooperationFilter
from langenv.control.trajectory import default_exercise
from langenv.env import LangCtrlEnv
from langenv.errors import ConfigError
from langenv.exercise import SHIPPED_EXERCISES, resolve_exercise
from langenv.motion.tick import GuidedArm
from langenv.robot.arm import Arm
from langenv.robot.force_sensor import ForceSensor
from langenv.robot.safety import SafetyLimits
from policies import load_policy


def _digest(env: gym.Env, seed: int) -> tuple[str, int]:
    """sha256 of every step's observation, reward and info values of an AC episode at 25 Hz."""
    policy = load_policy("ac")
    h = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    for k in range(2000):
        obs, reward, term, trunc, info = env.step(policy.act(obs))
        h.update(obs.tobytes() + float(reward).hex().encode())
        h.update(repr(sorted((key, repr(v)) for key, v in info.items())).encode())
        if term or trunc:
            return h.hexdigest(), k + 1
    raise AssertionError("episode did not end")


def _make(**kw: Any) -> gym.Env:
    return gym.make(langenv.ENV_ID, phrase_graph="ac", decision_hz=25, **kw)


def test_the_study_exercise_through_its_file_is_today_s_default_bit_for_bit() -> None:
    by_file = _digest(_make(exercise="external_rotation"), 3)
    by_code = _digest(_make(trajectory=default_exercise()), 3)
    default = _digest(_make(), 3)
    assert by_file == by_code == default
    assert by_file[1] > 100


def test_an_exercise_by_name_path_or_object(tmp_path: Path) -> None:
    path = SHIPPED_EXERCISES["hand_to_mouth"]
    for spec in ("hand_to_mouth", path, resolve_exercise(path)):
        env = gym.make(langenv.ENV_ID, exercise=spec)
        base: Any = env.unwrapped
        assert base.exercise.name == "hand_to_mouth"
        assert base.motion.trajectory is base.exercise.trajectory
        assert base.motion.params.propel_force == pytest.approx(0.125 * 80.0)
        assert base.graph.path.name == "hand_to_mouth_lc.yaml"  # the exercise's script
        env.close()


def test_bad_exercise_arguments_are_named() -> None:
    circle = resolve_exercise(Path(__file__).parent / "data" / "exercises" / "circle.yaml")
    with pytest.raises(ConfigError, match="trajectory has 1 legs, exercise 'hand_to_mouth' 3"):
        LangCtrlEnv(exercise="hand_to_mouth", trajectory=circle.trajectory)
    # the exercise's own path in another frame: the exercise names the legs of the script
    env = LangCtrlEnv(exercise="hand_to_mouth", trajectory=default_exercise())
    assert env.leg_plan.segments == 3 and env.exercise.name == "hand_to_mouth"
    with pytest.raises(ConfigError, match="external_rotation"):
        LangCtrlEnv(exercise="no_such_exercise")
    with pytest.raises(ConfigError, match="Exercise"):
        LangCtrlEnv(exercise=3)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", sorted(SHIPPED_EXERCISES))
def test_check_env_is_clean_for_every_exercise(name: str) -> None:
    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = gym.make(langenv.ENV_ID, exercise=name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a checker's warning fails the test
        gym_check(env.unwrapped, skip_render_check=True)
        sb3_check(env, warn=True)
    env.close()


@pytest.mark.parametrize("name", sorted(SHIPPED_EXERCISES))
def test_compiled_and_reference_ticks_agree_on_every_exercise(name: str) -> None:
    ex = resolve_exercise(name)

    def make(compiled: bool) -> GuidedArm:
        return GuidedArm(
            Arm(),
            ex.trajectory,
            ex.admittance(),
            ForceSensor(),
            CooperationFilter(),
            SafetyLimits(),
            compiled=compiled,
        )

    fast, ref = make(True), make(False)
    assert fast.compiled and not ref.compiled
    fast.reset()
    ref.reset()
    gen = np.random.default_rng(7)
    rng_a, rng_b = np.random.default_rng(3), np.random.default_rng(3)
    for i in range(3000):  # as tests/test_compiled_tick.py: noise, pushes along and against
        push = 5.0 if (i // 600) % 2 else -3.0
        f = gen.normal(0.0, 4.0, 3) + push * fast.tangent()
        p, p_dot = 1.0 + 0.3 * math.sin(i / 300), 0.5 * math.cos(i / 300)
        fast.tick(f, p, p_dot, rng_a)
        ref.tick(f, p, p_dot, rng_b)
        # bit-identical where the kernels' floating point matches NumPy's and MuJoCo's (the
        # pinned machines); within rounding elsewhere (this checks the geometry, not the FPU)
        np.testing.assert_allclose(fast.arm.data.qpos, ref.arm.data.qpos, rtol=0, atol=1e-9)
        assert fast.state.leg == ref.state.leg, f"tick {i}"
        assert math.isclose(fast.state.s, ref.state.s, abs_tol=1e-9), f"tick {i}"
        assert math.isclose(fast.t_x, ref.t_x, abs_tol=1e-6), f"tick {i}"
        assert math.isclose(fast.path_deviation, ref.path_deviation, abs_tol=1e-9)
    assert fast.state.leg >= 1  # the path was followed past a leg switch
