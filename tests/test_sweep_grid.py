"""Expanding a sweep: a fixed order, stable ids, seeds from the users, parameters where they
apply; the parameters themselves (eval.overrides)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eval.overrides import (
    apply_policy_params,
    env_kwargs_with,
    env_parameters,
    policy_parameters,
    resolve_policy_param,
)
from eval.sweep import expand, load_spec, session_id
from eval.sweep.driver import batch_size
from langenv.errors import ConfigError
from policies import load_policy

SPEC = """\
grid:
  policy: [ac, lc-noap, lc]
  phrase_graph: [lc, lc-noap]
  lc.k_c: [5.0, 10.0]
  env.deadband: {range: [4.0, 6.0, 1.0]}
sample:
  n: 3
  seed: 7
  space:
    lc.k_em: {uniform: [0.0, 1.0]}
    lc.terminal: {choice: [0.0, 1.0]}
users:
  - {synthetic: 2, first_seed: 10}
  - {synthetic: 1, first_seed: 10, name: again}
"""


def _load(tmp_path: Path, text: str = SPEC) -> list:  # type: ignore[type-arg]
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return expand(load_spec(path))


def test_expansion_is_fixed(tmp_path: Path) -> None:
    a, b = _load(tmp_path), _load(tmp_path)
    assert [s.session_id for s in a] == [s.session_id for s in b]
    assert [s.job for s in a] == [s.job for s in b]
    ids = [s.session_id for s in a]
    assert len(set(ids)) == len(ids)
    # ac and lc-noap: 2 deadbands x 3 users; lc: 2 graphs x 2 gains x 2 deadbands x 3 points x 3
    assert len(a) == 2 * (2 * 3) + 2 * 2 * 2 * 3 * 3
    assert [s.coords["policy"] for s in a[:6]] == ["ac"] * 6


def test_parameters_apply_to_their_policy_only(tmp_path: Path) -> None:
    sessions = _load(tmp_path)
    for s in sessions:
        own = s.coords["policy"] == "lc"
        assert (s.coords["lc.k_c"] is not None) == own
        assert (s.coords["sample"] is not None) == own
        assert (s.coords["phrase_graph"] is not None) == own
        assert s.coords["env.deadband"] in (4.0, 5.0)
        assert dict(s.job.env_params) == {"deadband": s.coords["env.deadband"]}
        if own:
            params = dict(s.job.params)
            assert params["gains.k_c"] == s.coords["lc.k_c"]
            assert 0.0 <= params["k_em"] <= 1.0 and params["terminal"] in (0.0, 1.0)
            assert s.job.phrase_graph == s.coords["phrase_graph"]
        else:
            assert s.job.params == () and s.job.phrase_graph is None


def test_seeds_come_from_users(tmp_path: Path) -> None:
    sessions = _load(tmp_path)
    for s in sessions:
        assert s.seed == s.job.seed == int(s.coords["user"][1:])
    assert {s.seed for s in sessions} == {10, 11}


def test_sample_points_are_drawn_once_per_spec(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(SPEC)
    spec = load_spec(path)
    assert spec.sample is not None
    assert spec.sample.points() == spec.sample.points()
    other = load_spec(path).sample
    assert other is not None and other.points() == spec.sample.points()


def test_session_id_is_pinned() -> None:
    """The id is part of the data format: a change breaks --resume of existing sweeps."""
    coords = {"policy": "lc", "lc.k_c": 5.0, "user": "s0"}
    assert session_id(coords, 0) == "d567ed3695ee7bb2"
    assert session_id(coords, 1) != session_id(coords, 0)
    assert session_id({**coords, "lc.k_c": 5.000001}, 0) != session_id(coords, 0)


@settings(max_examples=25, deadline=None)
@given(
    k=st.lists(st.floats(0.5, 30.0), min_size=1, max_size=4, unique=True),
    users=st.integers(1, 5),
    seed=st.integers(0, 1000),
)
def test_grid_size_and_unique_ids(
    tmp_path_factory: pytest.TempPathFactory, k: list[float], users: int, seed: int
) -> None:
    path = tmp_path_factory.mktemp("g") / "s.yaml"
    text = f"grid: {{policy: [ac, lc], lc.k_c: {k}}}\n"
    path.write_text(text + f"users: {{synthetic: {users}, first_seed: {seed}}}\n")
    sessions = expand(load_spec(path))
    assert len(sessions) == users * (1 + len(k))
    assert len({s.session_id for s in sessions}) == len(sessions)


def test_batch_size() -> None:
    assert batch_size(10, 2) == 1
    assert batch_size(2000, 2) == 16
    assert batch_size(2000, 2, 5) == 5


def test_policy_parameters_by_name() -> None:
    lc = load_policy("lc")
    assert "gains.k_c" in policy_parameters(lc) and "k_em" in policy_parameters(lc)
    assert policy_parameters(load_policy("ac")) == ()
    assert resolve_policy_param(lc, "k_c") == "gains.k_c"
    with pytest.raises(ConfigError, match=r"ambiguous: give one of gains\.k_a, limits\.k_a"):
        resolve_policy_param(lc, "k_a")
    with pytest.raises(ConfigError, match="unknown parameter 'name'"):
        resolve_policy_param(lc, "name")  # a str field is not a parameter
    tuned = apply_policy_params(lc, [("gains.k_c", 3.0), ("k_em", 0.5)])
    assert tuned.gains.k_c == 3.0 and tuned.k_em == 0.5 and lc.gains.k_c == 10.0
    with pytest.raises(ConfigError, match="k_c"):
        apply_policy_params(lc, [("gains.k_c", -1.0)])


def test_env_parameters_by_name() -> None:
    from langenv.control.admittance import AdmittanceParams

    params = env_parameters()
    assert "admittance.damping" in params and "w_em" in params and "safety.max_speed" in params
    assert "decision_hz" not in params and "width" not in params
    kwargs = env_kwargs_with({}, [("admittance.damping", 60.0), ("admittance.mass", 30.0)])
    assert kwargs["admittance"] == AdmittanceParams(damping=60.0, mass=30.0)
    with pytest.raises(ConfigError, match="unknown env parameter"):
        env_kwargs_with({}, [("admittance.colour", 1.0)])
