"""Training on the batched env: the residual LC's compiled twin against ResidualLC, the SB3
adapter against a DummyVecEnv of the same envs and wrappers, and the same PPO run either way."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv

import langenv  # noqa: F401
from langenv.errors import ConfigError
from langenv.task.observation import Obs, observation_size
from policies import residual_kernels as rk
from policies.learned import FEATURES, ResidualLC, ResidualSpec
from train.config import TrainArgs, resolve, wrapper_chain
from train.factories import use_batched
from train.vec_env import make_batched_vec_env

pytestmark = pytest.mark.xdist_group("batch")

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "ppo.yaml"
REWARD = {"w_em": 3.0, "w_adev": 2.0, "w_am_fine": 2.0, "am_scale": 0.02}


def _random_episode(rng: np.random.Generator, n_obs: int, steps: int) -> np.ndarray:
    """Observations a session might see: times falling, flags flipping, float32."""
    obs = rng.uniform(-1.0, 1.0, (steps, n_obs)).astype(np.float32)
    obs[:, Obs.T_X] = np.linspace(0.3, -0.01, steps) + rng.normal(0, 0.002, steps)
    obs[:, Obs.T_A] = np.linspace(0.28, 0.0, steps) + rng.normal(0, 0.002, steps)
    obs[:, Obs.ELAPSED] = np.linspace(-1.0, -0.6, steps)
    obs[steps // 2 :, Obs.ELAPSED] = obs[steps // 2, Obs.ELAPSED]  # time stands still a while
    obs[:, Obs.MOTION_DONE] = np.where(np.arange(steps) > 0.8 * steps, 1.0, -1.0)
    obs[:, Obs.SPEECH_DONE] = np.where(np.arange(steps) > 0.9 * steps, 1.0, -1.0)
    return obs


@pytest.mark.parametrize(
    "spec",
    [
        ResidualSpec("target", 3, 0.5, 0.5, 0.1, 25, terminal=1.0, k_em=1.0),
        ResidualSpec("scores", 3, 0.3, 0.7, None, 25, terminal=0.0, gate_em=0.05, deadband=0.2),
        ResidualSpec("target", 2, 0.0, 0.4, 0.0, 50, terminal=2.0),
    ],
)
def test_the_compiled_residual_is_residual_lc(spec: ResidualSpec) -> None:
    n, steps = 3, 60
    n_obs = observation_size(spec.max_children)
    rng = np.random.default_rng(3)
    episodes = [_random_episode(rng, n_obs, steps) for _ in range(n)]
    cores = [ResidualLC(spec) for _ in range(n)]
    prm = rk.residual_params(spec)
    state, last = rk.RESIDUAL_STATE.zeros(n), np.zeros((n, n_obs), np.float32)
    out = np.zeros((n, n_obs + len(FEATURES)), np.float32)
    act = np.zeros((n, spec.action_dim), np.float32)
    for t in range(steps):
        obs = np.stack([e[t] for e in episodes])
        rk.observe(obs, np.full(n, t == 0), last, state, prm, out)
        r = rng.uniform(-1.2, 1.2, (n, spec.action_dim))
        rk.act(r, last, state, prm, act)
        for i, core in enumerate(cores):
            ref = core.start(obs[i].copy()) if t == 0 else core.observe(obs[i].copy())
            assert np.array_equal(ref.astype(np.float32), out[i]), (t, i)
            assert np.array_equal(core.action(r[i]), act[i]), (t, i)


def _recipe_wrappers(mode: str) -> list[tuple[str, dict[str, Any]]]:
    return [
        ("train.wrappers.AlignmentReward", REWARD),
        (
            "train.wrappers.ResidualLCWrapper",
            {"pace_scale": 0.5, "audio_scale": 0.1, "choice_scale": 0.5, "choice_mode": mode,
             "terminal": 1.0, "k_em": 1.0},
        ),
    ]  # fmt: skip


@pytest.mark.parametrize("mode", ["target", "scores"])
def test_the_adapter_is_a_dummy_vec_env_of_the_same_envs(mode: str) -> None:
    """Observations, float32 rewards, dones, terminal observations and the Monitor's episode
    records: bit for bit, through episode ends (a short time limit makes many)."""
    n = 3
    kwargs = {"choice_mode": mode, "w_em": 0.0, "w_pace": 0.1, "w_am": 6.0}
    wrappers = _recipe_wrappers(mode)
    chain = wrapper_chain([{k: v} for k, v in wrappers], CONFIG)
    ref = make_vec_env(
        "LangCtrl-v0", n_envs=n, seed=1000, vec_env_cls=DummyVecEnv,
        env_kwargs={**kwargs, "max_episode_steps": 120}, wrapper_class=chain,
    )  # fmt: skip
    got = make_batched_vec_env(n, {**kwargs, "max_episode_steps": 120}, 1000, wrappers)
    assert ref.observation_space == got.observation_space
    assert ref.action_space == got.action_space
    assert np.array_equal(ref.reset(), got.reset())
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(300):
        a = rng.uniform(-1, 1, (n, *got.action_space.shape)).astype(np.float32)  # type: ignore[misc]
        o1, r1, d1, i1 = ref.step(a)
        o2, r2, d2, i2 = got.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        assert r2.dtype == np.float32
        for i in np.flatnonzero(d1).tolist():
            ends += 1
            assert np.array_equal(i1[i]["terminal_observation"], i2[i]["terminal_observation"])
            assert i1[i]["TimeLimit.truncated"] == i2[i]["TimeLimit.truncated"]
            assert i1[i]["episode"]["r"] == i2[i]["episode"]["r"]
            assert i1[i]["episode"]["l"] == i2[i]["episode"]["l"]
    assert ends >= 6
    assert got.get_attr("residual_spec")[0] == ref.get_attr("residual_spec")[0]
    ref.close()
    got.close()


def test_the_wrapper_and_the_batch_shape_the_reward_alike(monkeypatch: pytest.MonkeyPatch) -> None:
    """``AlignmentReward`` on single envs and the batch, both with the one set of defaults
    (:class:`train.shaping.AlignmentShaping`): the same shaped reward (float64, before SB3's
    float32), bit for bit, at every step of episodes that end by themselves (the ``|AM|`` term
    paid)."""
    import gymnasium as gym

    from train.shaping import AlignmentShaping
    from train.vec_env import BatchedVecEnv
    from train.wrappers import AlignmentReward

    shaped: list[np.ndarray] = []
    batch_shape = BatchedVecEnv._shape

    def spy(self: BatchedVecEnv, *args: Any) -> np.ndarray:
        out = batch_shape(self, *args)
        shaped.append(out.copy())
        return out

    monkeypatch.setattr(BatchedVecEnv, "_shape", spy)
    n, kwargs = 2, {"decision_hz": 25, "w_em": 0.0, "w_pace": 0.1, "w_am": 6.0}
    wrapped = [("train.wrappers.AlignmentReward", {})]
    got = make_batched_vec_env(n, {**kwargs, "max_episode_steps": 2000}, 1000, wrapped)
    singles = [
        AlignmentReward(gym.make("LangCtrl-v0", max_episode_steps=2000, **kwargs)) for _ in range(n)
    ]
    assert all(env.shaping == AlignmentShaping() for env in singles)
    got.reset()
    for i, env in enumerate(singles):
        env.reset(seed=1000 + i)
    action = np.zeros((n, *got.action_space.shape), np.float32)  # type: ignore[misc]
    going, paid = [True] * n, 0
    while any(going):
        got.step(action)
        for i, env in enumerate(singles):
            if not going[i]:
                continue
            _, reward, term, trunc, info = env.step(action[i])
            assert reward == shaped[-1][i], (len(shaped), i)
            terms = (info["reward_em_base"], info["reward_adev"], info["reward_am_fine"])
            assert all(t <= 0.0 for t in terms)
            paid += term and info["reward_am_fine"] < 0.0
            going[i] = not (term or trunc)
    assert paid == n
    got.close()


def test_auto_is_batched_where_it_applies() -> None:
    run = resolve(TrainArgs(config=CONFIG, n_eval_episodes=0))
    assert run.args.vec_env == "auto" and use_batched("auto", run)
    assert not use_batched("dummy", run) and not use_batched("subproc", run)
    general = CONFIG.parent / "ppo_general.yaml"
    worlds = resolve(TrainArgs(config=general, n_eval_episodes=0))
    assert not use_batched("auto", worlds)
    with pytest.raises(ConfigError, match="worlds"):
        use_batched("batched", worlds)
    with pytest.raises(ConfigError, match="no batched form"):
        make_batched_vec_env(1, {}, 0, [("train.wrappers.SeedCycle", {"seeds": [1]})])


@pytest.mark.slow
def test_a_batched_run_is_the_dummy_run(tmp_path: Path) -> None:
    """The same config, envs and seeds: the same model after an update, bit for bit."""
    import torch
    from stable_baselines3 import PPO

    from train.ppo import train

    models = {}
    for vec_env in ("dummy", "batched"):
        args = TrainArgs(
            config=CONFIG, out=tmp_path / vec_env, total_timesteps=512, n_envs=2,
            vec_env=vec_env, n_eval_episodes=0, progress_bar=False, tensorboard=False,
            checkpoint_freq=10**6,
        )  # fmt: skip
        models[vec_env] = PPO.load(train(args)).policy.state_dict()
    a, b = models["dummy"], models["batched"]
    assert all(torch.equal(a[k], b[k]) for k in a)
