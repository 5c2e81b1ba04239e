"""Perturbed synthetic users: the population plus behaviours the analytic rules do not model."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.env import LangCtrlEnv
from langenv.errors import ConfigError
from langenv.users import PERTURBATIONS, Perturbations, PerturbedUser, SyntheticUser


def _only(kind: str, **ranges: Any) -> Perturbations:
    return Perturbations(weights={kind: 1.0}, **ranges)


def _user(kind: str, seed: int, **ranges: Any) -> PerturbedUser:
    user = PerturbedUser(_only(kind, **ranges))
    user.reset(np.random.default_rng(seed))
    return user


def test_none_is_the_synthetic_person_of_the_same_seed() -> None:
    plain = SyntheticUser()
    plain.reset(np.random.default_rng(7))
    same = _user("none", 7)
    assert same.kind == "none"
    assert same.f_applied.tobytes() == plain.f_applied.tobytes()


def test_speeds_up_late_pushes_along_the_motion_after_its_onset() -> None:
    u = _user("speeds_up_late", 1, late_onset=(5.0, 5.0), push=(10.0, 10.0))
    t = u.grid
    assert np.all(u.f_applied[t > 5.6] == pytest.approx(-10.0))
    assert np.all(u.f_applied[t > 5.0] <= 0.0)
    assert u.force(8.0, np.zeros(3), np.array([1.0, 0.0, 0.0]))[0] == pytest.approx(10.0)


def test_stop_restart_holds_then_lets_go() -> None:
    u = _user("stop_restart", 2, stop_onset=(3.0, 3.0), stop_duration=(2.0, 2.0), hold=(9, 9))
    dead = u.params.deadband
    t = u.grid
    hold = (t > 3.25) & (t < 4.75)
    assert np.all(u.f_applied[hold] >= 9.0 + dead - 1e-9)
    plain = SyntheticUser()
    plain.reset(np.random.default_rng(2))
    after = t > 5.1
    assert np.array_equal(u.f_applied[after], plain.f_applied[after])


def test_tremor_oscillates_at_its_frequency() -> None:
    u = _user("tremor", 3, tremor_hz=(5.0, 5.0), tremor_amplitude=(6.0, 6.0))
    plain = SyntheticUser()
    plain.reset(np.random.default_rng(3))
    wave = u.f_applied - plain.f_applied
    spectrum = np.abs(np.fft.rfft(wave[:2000]))
    freqs = np.fft.rfftfreq(2000, u.params.resolution)
    assert freqs[int(np.argmax(spectrum[1:])) + 1] == pytest.approx(5.0, abs=0.1)
    assert np.max(np.abs(wave)) <= 6.0 + 1e-9


def test_lag_slows_the_release() -> None:
    kw = {"lag_tau": (2.0, 2.0)}
    for seed in range(20):
        u = _user("lagged", seed, **kw)
        plain = SyntheticUser()
        plain.reset(np.random.default_rng(seed))
        if plain.episodes:
            break
    assert plain.episodes
    end = plain.episodes[0].end
    k = int(np.searchsorted(u.grid, end + 0.2))
    assert plain.f_applied[k] == 0.0 or plain.episodes[0].end < end + 0.2
    assert u.f_applied[k] > 0.0  # still resisting after the drawn person let go
    assert np.max(np.abs(np.diff(u.f_applied[u.f_applied > 0]))) < np.max(
        np.abs(np.diff(plain.f_applied))
    )


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(PERTURBATIONS))
def test_force_stays_within_the_populations_cap(seed: int, kind: str) -> None:
    u = _user(kind, seed)
    cap = u.params.max_excess + u.params.deadband
    assert np.all(np.isfinite(u.f_applied)) and np.max(np.abs(u.f_applied)) <= cap + 1e-9


def test_same_seed_same_person_and_mix_draws_every_kind() -> None:
    a, b = PerturbedUser(), PerturbedUser()
    kinds = set()
    for seed in range(60):
        a.reset(np.random.default_rng(seed))
        b.reset(np.random.default_rng(seed))
        assert a.kind == b.kind and a.f_applied.tobytes() == b.f_applied.tobytes()
        kinds.add(a.kind)
    assert kinds == set(PERTURBATIONS)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"weights": {"wobble": 1.0}}, "unknown kind"),
        ({"weights": {"none": 0.0}}, "not all 0"),
        ({"push": (5.0, 1.0)}, "push"),
        ({"tremor_hz": (4.0, 30.0)}, "tremor_hz"),
        ({"lag_tau": "slow"}, "lag_tau"),
    ],
)
def test_bad_perturbations_are_named(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        Perturbations(**kwargs)
    with pytest.raises(ConfigError, match="here"):
        Perturbations.from_dict(kwargs, "here")


@pytest.mark.parametrize("kind", PERTURBATIONS[1:])
def test_compiled_ticks_equal_python_ticks(kind: str) -> None:
    fast = LangCtrlEnv(users=PerturbedUser(_only(kind)))
    ref = LangCtrlEnv(users=PerturbedUser(_only(kind)))
    ref._steps = None  # the Python ticks
    oa, _ = fast.reset(seed=11)
    ob, _ = ref.reset(seed=11)
    assert fast._steps is not None and fast._steps.usable()
    assert oa.tobytes() == ob.tobytes()
    for k in range(2000):
        a, b = fast.step(np.zeros(3)), ref.step(np.zeros(3))
        assert a[0].tobytes() == b[0].tobytes(), f"step {k}"
        assert a[1:4] == b[1:4]
        if a[2] or a[3]:
            break
    assert a[2]  # the episode ended by itself
