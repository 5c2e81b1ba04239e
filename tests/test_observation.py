"""The observation's one home (langenv/task/observation.py): encoders and decoders agree, and the
env writes what its ``info`` reports, where the policies read it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import langenv
from langenv.task import observation as ob
from langenv.task.observation import ChildField, Obs, ObservationEncoder

F32 = 1e-6  # the observation is float32: about 7 significant digits


@given(st.floats(-40.0, 40.0))
def test_seconds_round_trip(t: float) -> None:
    obs = np.zeros(ob.observation_size(1), np.float32)
    obs[Obs.T_X] = ob.encode_seconds(t)
    assert ob.seconds(obs, Obs.T_X) == pytest.approx(t, abs=40 * F32)


@given(st.floats(0.6, 1.4), st.floats(0.0, 1.0), st.floats(0.0, 60.0), st.floats(0.0, 0.25))
def test_other_fields_round_trip(p: float, c: float, t: float, v: float) -> None:
    obs = np.zeros(ob.observation_size(1), np.float32)
    obs[Obs.P] = ob.encode_pace(p)
    obs[Obs.COOPERATION] = ob.encode_fraction(c)
    obs[Obs.ELAPSED] = ob.encode_elapsed(t)
    obs[Obs.HAND_SPEED] = ob.encode_speed(v)
    obs[Obs.MOTION_DONE] = ob.encode_flag(True)
    obs[Obs.SPEECH_DONE] = ob.encode_flag(False)
    assert ob.pace(obs, Obs.P) == pytest.approx(p, abs=F32)
    assert ob.fraction(obs, Obs.COOPERATION) == pytest.approx(c, abs=F32)
    assert ob.elapsed(obs) == pytest.approx(t, abs=60 * F32)
    assert ob.hand_speed(obs) == pytest.approx(v, abs=F32)
    assert ob.flag(obs, Obs.MOTION_DONE) and not ob.flag(obs, Obs.SPEECH_DONE)


def test_layout_indices() -> None:
    assert ob.FIRST_CHILD == len(Obs) == 16 and ob.CHILD_FIELDS == 3
    assert ob.observation_size(10) == 46
    assert ob.child_index(2, ChildField.T_MAX) == 16 + 3 * 2 + 2


def test_encoder_clips_and_marks_missing_children() -> None:
    enc = ObservationEncoder(3, {"x": (2.0, 80.0)})
    out = np.zeros(enc.size, np.float32)
    enc.encode(
        out,
        t_x=100.0,
        t_a=0.0,
        p=1.6,
        a=1.0,
        cooperation=1.0,
        cooperation_trend=0.0,
        progress=0.0,
        hand_speed=0.0,
        phrase_said=0.0,
        phrase_left=0.0,
        in_pause=False,
        speech_done=False,
        motion_done=False,
        boundary_due=True,
        elapsed=0.0,
        children=("x",),
    )
    assert out[Obs.T_X] == 1.0 and out[Obs.P] == 1.0  # beyond the scale: reads as +1
    assert ob.child(out, 0) == (True, pytest.approx(2.0), 40.0)
    assert ob.child(out, 1) == (False, 0.0, 0.0) and ob.child(out, 2) == (False, 0.0, 0.0)
    assert ob.child(out, 3) is None
    assert ob.flag(out, Obs.BOUNDARY_DUE)


def _reference_encode(enc: ObservationEncoder, fields: dict[str, object]) -> np.ndarray:
    """The encoder's definition, written plainly: every entry in float32, then ``np.clip``."""
    f = fields
    header = [
        ob.encode_seconds(f["t_x"]),
        ob.encode_seconds(f["t_a"]),
        ob.encode_seconds(f["t_a"] / f["a"] - f["t_x"] / f["p"]),
        ob.encode_pace(f["p"]),
        ob.encode_pace(f["a"]),
        ob.encode_fraction(f["cooperation"]),
        f["cooperation_trend"],
        ob.encode_fraction(f["progress"]),
        ob.encode_speed(f["hand_speed"]),
        ob.encode_fraction(f["phrase_said"]),
        ob.encode_seconds(f["phrase_left"]),
        *(ob.encode_flag(f[k]) for k in ("in_pause", "speech_done", "motion_done", "boundary_due")),
        ob.encode_elapsed(f["elapsed"]),
    ]
    out = np.zeros(enc.size, np.float32)
    out[: ob.FIRST_CHILD] = header
    for k, c in enumerate(f["children"]):  # type: ignore[call-overload]
        t_min, t_max = _DURATIONS[c]
        out[ob.child_index(k) : ob.child_index(k) + 3] = (
            1.0,
            ob.encode_seconds(t_min),
            ob.encode_seconds(t_max),
        )
    for k in range(len(f["children"]), enc.max_children):  # type: ignore[arg-type]
        out[ob.child_index(k)] = -1.0
    return np.clip(out, -1.0, 1.0)


_DURATIONS = {"x": (2.0, 80.0), "y": (0.5, 3.0), "z": (39.99999, 40.00001)}
_anything = st.floats(allow_nan=True, allow_infinity=True, width=64)
_positive = st.floats(1e-3, 1e3)


@given(
    st.fixed_dictionaries(
        {
            "t_x": _anything,
            "t_a": _anything,
            "p": _positive,
            "a": _positive,
            "cooperation": _anything,
            "cooperation_trend": _anything,
            "progress": _anything,
            "hand_speed": _anything,
            "phrase_said": _anything,
            "phrase_left": _anything,
            "in_pause": st.booleans(),
            "speech_done": st.booleans(),
            "motion_done": st.booleans(),
            "boundary_due": st.booleans(),
            "elapsed": _anything,
            "children": st.lists(st.sampled_from(sorted(_DURATIONS)), max_size=3).map(tuple),
        }
    )
)
def test_encoder_equals_its_plain_definition(fields: dict[str, object]) -> None:
    """The fast encoder (clipping in float64 before the float32 rounding, cached child blocks)
    writes exactly what casting to float32 and then clipping writes, NaN included."""
    enc = ObservationEncoder(3, _DURATIONS)
    out = np.full(enc.size, 7.0, np.float32)
    with np.errstate(all="ignore"):
        enc.encode(out, **fields)  # type: ignore[arg-type]
        ref = _reference_encode(enc, fields)
    np.testing.assert_array_equal(out, ref)


def test_env_writes_what_its_info_reports() -> None:
    """Decoding the env's observation gives the values of its ``info``, step by step, and the
    child blocks hold the current phrase's children's durations."""
    env = gym.make(langenv.ENV_ID, decision_hz=25)
    base = env.unwrapped
    assert env.observation_space.shape == (ob.observation_size(base.max_children),)
    obs, info = env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(1500):
        assert ob.seconds(obs, Obs.T_X) == pytest.approx(info["t_x"], abs=40 * F32)
        assert ob.seconds(obs, Obs.T_A) == pytest.approx(info["t_a"], abs=40 * F32)
        assert ob.pace(obs, Obs.P) == pytest.approx(info["p"], abs=F32)
        assert ob.pace(obs, Obs.A) == pytest.approx(info["a"], abs=F32)
        assert ob.fraction(obs, Obs.COOPERATION) == pytest.approx(info["cooperation"], abs=F32)
        assert ob.fraction(obs, Obs.PROGRESS) == pytest.approx(info["progress"], abs=F32)
        assert ob.hand_speed(obs) == pytest.approx(info["hand_speed"], abs=F32)
        assert ob.elapsed(obs) == pytest.approx(info["time"], abs=60 * F32)
        assert ob.flag(obs, Obs.MOTION_DONE) == info["motion_done"]
        assert ob.flag(obs, Obs.SPEECH_DONE) == info["speech_done"]
        assert ob.flag(obs, Obs.IN_PAUSE) == info["in_pause"]
        children = base.speech.candidates
        for k in range(base.max_children):
            valid, t_min, t_max = ob.child(obs, k)  # type: ignore[misc]
            assert valid == (k < len(children))
            if valid:
                assert t_min == pytest.approx(base.graph.t_min(children[k]), abs=40 * F32)
                assert t_max == pytest.approx(base.graph.t_max(children[k]), abs=40 * F32)
        action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        obs, _, term, trunc, info = env.step(action)
        if term or trunc:
            break
    assert term or trunc
