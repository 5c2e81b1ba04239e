"""The env's compiled ticks (langenv.env_kernels) against its Python ticks: bit-identical."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.compiled_steps import CompiledSteps
from langenv.control.admittance import AdmittanceParams
from langenv.control.cooperation import CooperationFilter
from langenv.control.trajectory import default_exercise
from langenv.env import LangCtrlEnv
from langenv.kernels import mjc
from langenv.motion.tick import GuidedArm
from langenv.robot.arm import Arm
from langenv.robot.force_sensor import ForceSensor
from langenv.users import ReplayUser, SyntheticUser
from langenv.users.session_csv import Session
from langenv.users.synthetic import LogNormal, SyntheticUserParams

pytestmark = pytest.mark.portable


def _pair(**kwargs: Any) -> tuple[LangCtrlEnv, LangCtrlEnv]:
    fast, ref = LangCtrlEnv(**kwargs), LangCtrlEnv(**kwargs)
    ref._steps = None  # the Python ticks (with the compiled motion tick)
    return fast, ref


def _same_step(a: tuple[Any, ...], b: tuple[Any, ...], k: int) -> None:
    assert a[0].tobytes() == b[0].tobytes(), f"step {k}: observations differ"
    assert a[1:4] == b[1:4], f"step {k}: reward/flags {a[1:4]} != {b[1:4]}"
    assert a[4] == b[4], f"step {k}: info differs"


def _episode(fast: LangCtrlEnv, ref: LangCtrlEnv, seed: int, actions: Any) -> list[str]:
    """One episode of both envs on the same actions; every step's output equal."""
    calls: list[str] = []
    assert fast._steps is not None
    run = fast._steps.run

    def spy(*args: Any) -> Any:
        out = run(*args)
        calls.append(str(out[1]))
        return out

    fast._steps.run = spy  # type: ignore[method-assign]
    oa, ia = fast.reset(seed=seed)
    ob, ib = ref.reset(seed=seed)
    assert oa.tobytes() == ob.tobytes() and ia == ib
    for k in range(3000):
        act = actions(k)
        a, b = fast.step(act), ref.step(act)
        _same_step(a, b, k)
        if a[2]:
            break
    assert fast.speech.path == ref.speech.path
    return calls


@pytest.mark.parametrize(
    ("hz", "mode", "seed"),
    [(25, "target", 0), (25, "scores", 1), (50, "target", 2), (500, "target", 3)],
)
def test_synthetic_users_random_actions(hz: int, mode: str, seed: int) -> None:
    fast, ref = _pair(decision_hz=hz, choice_mode=mode)
    gen = np.random.default_rng(seed)
    shape = fast.action_space.shape
    steady = gen.uniform(-1.0, 1.0, shape)
    calls = _episode(fast, ref, seed, lambda k: steady if k % 40 else gen.uniform(-1, 1, shape))
    assert "0" in calls and "1" in calls  # compiled ticks and phrase boundaries in Python


def test_replay_user() -> None:
    t = np.linspace(0.0, 20.0, 401)
    session = Session("made", t, np.clip(0.6 + 0.4 * np.cos(t), 0.0, 1.0))
    fast, ref = _pair(users=ReplayUser(session))
    _episode(fast, ref, 0, lambda k: np.zeros(3))


def test_protective_stop() -> None:
    params = SyntheticUserParams.calibrated(
        count_pmf=(0.0, 1.0), p_start_resisting=1.0, max_excess=400.0,
        magnitude=LogNormal(300.0, 0.01), rise=LogNormal(0.5, 0.01),
    )  # fmt: skip
    fast, ref = _pair(users=SyntheticUser(params))
    calls = _episode(fast, ref, 0, lambda k: np.zeros(3))
    assert fast.motion.safety_stop is not None and fast.motion.safety_stop.limit == "force"
    assert str(3) in calls  # R_STOP


def test_joint_limit_avoidance_and_python_fallbacks() -> None:
    fast, ref = _pair()
    for env in (fast, ref):  # margins wider than the joints' room: the re-solve every tick
        env.motion = GuidedArm(
            Arm(joint_limit_margin=4.5), default_exercise(), AdmittanceParams(),
            ForceSensor(), CooperationFilter(),
        )  # fmt: skip
    fast._steps = CompiledSteps(fast)
    calls = []
    for _ in range(2):
        calls += _episode(fast, ref, 4, lambda k: np.array([0.2, -0.1, 0.0]))
    assert str(2) in calls  # R_CONTROL
    fast, ref = _pair(sensor_noise=1.0)
    assert fast._steps is not None and not fast._steps.usable()


_POW = mjc.pow_address()


@settings(max_examples=300, deadline=None)
@given(st.floats(-3.0, 3.0, allow_nan=False))
def test_compiled_square_is_pythons(x: float) -> None:
    assert mjc.py_square(_POW, x) == x**2


def test_compiled_square_on_a_dense_sample() -> None:
    xs = np.random.default_rng(0).uniform(-0.8, 0.8, 20000).tolist()
    assert all(mjc.py_square(_POW, x) == x**2 for x in xs)
    assert any(x * x != x**2 for x in xs)  # the case that needs pow
