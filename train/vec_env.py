"""The batched env (:mod:`langenv.batch`) as Stable-Baselines3's ``VecEnv``, with the training
wrappers applied to the whole batch.

:class:`BatchedVecEnv` steps a :class:`~langenv.batch.LangCtrlVectorEnv` (``SAME_STEP``
autoreset, what SB3 expects) and gives SB3 what a ``DummyVecEnv`` of ``make_vec_env``'s envs
gives: float32 rewards, ``dones``, and per session an info dict holding, where an episode ended,
``terminal_observation``, ``TimeLimit.truncated`` and ``episode`` (the env's own return and
length, as SB3's ``Monitor`` records them) and the final info values. The config's wrappers act
on the batch, the same arithmetic as the single env's (``tests/test_train_batched.py``):

* ``train.wrappers.AlignmentReward``: the reward terms on the info arrays (one
  :class:`~train.shaping.AlignmentShaping` for both);
* ``train.wrappers.ResidualLCWrapper``: the correction of the analytic base and the features, in
  compiled code (:mod:`policies.residual_kernels`, the twin of
  :class:`~policies.learned.ResidualLC`).

So a run on ``BatchedVecEnv`` with the same envs and seeds is the run ``DummyVecEnv`` gives, in
far fewer calls.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from langenv.errors import ConfigError
from policies import residual_kernels as rk
from policies.learned import FEATURES, ResidualSpec
from train.shaping import AlignmentShaping

__all__ = ["BATCHED_WRAPPERS", "BatchedVecEnv", "make_batched_vec_env"]

BATCHED_WRAPPERS = ("train.wrappers.AlignmentReward", "train.wrappers.ResidualLCWrapper")
"""The wrappers a batched run applies to the batch (any other needs a per-env vec env)."""

_KEEP_FINAL = ("am", "t_motion", "t_speech", "safety_stop", "time", "em", "a")


class BatchedVecEnv(VecEnv):
    """SB3's ``VecEnv`` over a :class:`~langenv.batch.LangCtrlVectorEnv`.

    Args:
        venv: The batched env (built with ``autoreset_mode=SAME_STEP``).
        reward: ``AlignmentReward``'s keyword arguments, or None for none.
        residual: ``ResidualLCWrapper``'s keyword arguments, or None for none.

    Raises:
        ConfigError: for a batched env of another autoreset mode or bad wrapper arguments.
    """

    def __init__(
        self,
        venv: Any,
        reward: dict[str, Any] | None = None,
        residual: dict[str, Any] | None = None,
    ) -> None:
        if venv.autoreset_mode != AutoresetMode.SAME_STEP:
            raise ConfigError("BatchedVecEnv needs a batched env with autoreset_mode SAME_STEP")
        self.venv = venv
        n = venv.num_envs
        base = venv.envs[0]
        obs_space: spaces.Box = venv.single_observation_space
        act_space: spaces.Box = venv.single_action_space
        self.residual_spec: ResidualSpec | None = None
        if residual is not None:
            self.residual_spec = _residual_spec(base, residual)
            size = int(obs_space.shape[0]) + len(FEATURES)
            obs_space = spaces.Box(-1.0, 1.0, (size,), np.float32)
            act_space = spaces.Box(-1.0, 1.0, (self.residual_spec.action_dim,), np.float32)
            self._params = rk.residual_params(self.residual_spec, base.paces.limits)
            self._state = rk.RESIDUAL_STATE.zeros(n)
            self._last = np.zeros((n, venv.single_observation_space.shape[0]), np.float32)
        self._reward = AlignmentShaping.from_kwargs(reward) if reward is not None else None
        self.render_mode = None
        super().__init__(n, obs_space, act_space)
        self._actions: np.ndarray | None = None
        self._time = np.zeros(n)
        self._ret = np.zeros(n)
        self._len = np.zeros(n, np.int64)
        self._t0 = time.time()

    # ------------------------------------------------------------------ VecEnv
    def reset(self) -> np.ndarray:
        seeds = list(self._seeds)
        options = self._options[0] if self._options and self._options[0] else None
        obs, infos = self.venv.reset(
            seed=None if all(s is None for s in seeds) else seeds, options=options
        )
        self._reset_seeds()
        self._reset_options()
        self._time[:] = infos["time"]
        self._ret[:] = 0.0
        self._len[:] = 0
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return self._augment(obs, np.ones(self.num_envs, bool))

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        assert self._actions is not None
        n = self.num_envs
        env_actions = self._env_actions(self._actions)
        obs, reward, term, trunc, infos = self.venv.step(env_actions)
        done = term | trunc
        final = infos.get("final_info", {})
        # the step's own values: the final info where the episode ended (then reset)
        step_info = {k: _pick(infos, final, k, done) for k in ("time", "em", "a", "am")}
        step_info["motion_done"] = _pick_flag(infos, final, "motion_done", done)
        step_info["speech_done"] = _pick_flag(infos, final, "speech_done", done)
        self._ret += reward
        self._len += 1
        total = reward.copy()
        if self._reward is not None:
            total = self._shape(reward, term, step_info)
        self._time[:] = infos["time"]  # the next step's start (a new episode's 0.0 where reset)
        rewards = total.astype(np.float32)  # DummyVecEnv's reward buffer is float32
        out_infos: list[dict[str, Any]] = [{} for _ in range(n)]
        terminal: dict[int, np.ndarray] = {}
        if done.any():
            idx = np.flatnonzero(done)
            final_obs = np.stack([infos["final_obs"][i] for i in idx.tolist()])
            if self.residual_spec is not None:
                terminal_aug = self._observe(final_obs, idx, start=False)
                for k, i in enumerate(idx.tolist()):
                    terminal[i] = terminal_aug[k]
            else:
                for k, i in enumerate(idx.tolist()):
                    terminal[i] = final_obs[k]
            now = round(time.time() - self._t0, 6)
            for i in idx.tolist():
                info: dict[str, Any] = {
                    key: _value(final, key, i) for key in _KEEP_FINAL if key in final
                }
                info["terminal_observation"] = terminal[i]
                info["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
                info["episode"] = {
                    "r": round(float(self._ret[i]), 6),
                    "l": int(self._len[i]),
                    "t": now,
                }
                out_infos[i] = info
            self._ret[idx] = 0.0
            self._len[idx] = 0
        if self.residual_spec is not None:
            obs = self._augment(obs, done)
        return obs, rewards, done, out_infos

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """``residual_spec`` (the batch's wrapper's) and the sessions' own attributes."""
        which = self._get_indices(indices)
        if attr_name == "residual_spec":
            if self.residual_spec is None:
                raise AttributeError("residual_spec")
            return [self.residual_spec for _ in which]
        return [getattr(self.venv.envs[i], attr_name) for i in which]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for i in self._get_indices(indices):
            setattr(self.venv.envs[i], attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        self.venv.sync()
        return [
            getattr(self.venv.envs[i], method_name)(*method_args, **kwargs)
            for i in self._get_indices(indices)
        ]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]

    # ------------------------------------------------------------------ the wrappers
    def _env_actions(self, actions: np.ndarray) -> np.ndarray:
        if self.residual_spec is None:
            return actions
        r = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, -1)
        if r.shape[1] != self.residual_spec.action_dim:
            raise ConfigError(
                f"residual must have shape ({self.residual_spec.action_dim},), got {r.shape[1:]}"
            )
        if not np.all(np.isfinite(r)):
            raise ConfigError("residual must be finite")
        out = np.zeros((self.num_envs, self.residual_spec.action_dim), np.float32)
        rk.act(r, self._last, self._state, self._params, out)
        return out

    def _observe(self, obs: np.ndarray, which: np.ndarray, start: bool) -> np.ndarray:
        """The features of the sessions ``which`` after their observations ``obs``."""
        n_aug = int(self.observation_space.shape[0])  # type: ignore[index]
        out = np.zeros((which.size, n_aug), np.float32)
        last, state = self._last[which], self._state[which]
        rk.observe(
            np.ascontiguousarray(obs, np.float32), np.full(which.size, start), last, state,
            self._params, out,
        )  # fmt: skip
        self._last[which], self._state[which] = last, state
        return out

    def _augment(self, obs: np.ndarray, starting: np.ndarray) -> np.ndarray:
        """The batch's observations, augmented (``starting``: a session's first of an
        episode)."""
        if self.residual_spec is None:
            return obs
        out = np.zeros((self.num_envs, int(self.observation_space.shape[0])), np.float32)  # type: ignore[index]
        rk.observe(
            np.ascontiguousarray(obs, np.float32), starting, self._last, self._state,
            self._params, out,
        )  # fmt: skip
        return out

    def _shape(
        self, reward: np.ndarray, term: np.ndarray, info: dict[str, np.ndarray]
    ) -> np.ndarray:
        """``AlignmentReward`` on the batch: its terms (:mod:`train.shaping`), in its order."""
        assert self._reward is not None
        r_em, r_adev, r_am = self._reward.terms(
            info["time"] - self._time, info["em"], info["a"], info["motion_done"],
            info["speech_done"], term, info["am"],
        )  # fmt: skip
        return reward + r_em + r_adev + r_am


def make_batched_vec_env(
    n_envs: int,
    env_kwargs: dict[str, Any],
    seed: int | None,
    wrappers: Sequence[tuple[str, dict[str, Any]]],
    session_kwargs: Sequence[dict[str, Any]] | None = None,
    parallel: str = "pool",
) -> BatchedVecEnv:
    """A :class:`BatchedVecEnv` of ``n_envs`` sessions of ``LangCtrl-v0`` with ``env_kwargs``
    (``max_episode_steps`` included), the config's ``wrappers`` (dotted class name, keyword
    arguments; innermost first: :data:`BATCHED_WRAPPERS` only) and session ``i`` seeded
    ``seed + i`` at its first reset, as ``make_vec_env`` seeds its envs.

    Raises:
        ConfigError: for a wrapper the batch cannot apply.
    """
    from langenv.batch import LangCtrlVectorEnv

    kwargs = dict(env_kwargs)  # without max_episode_steps: each session's max_seconds
    venv = LangCtrlVectorEnv(
        n_envs,
        autoreset_mode=AutoresetMode.SAME_STEP,
        parallel=parallel,  # type: ignore[arg-type]
        session_kwargs=session_kwargs,
        **kwargs,
    )
    reward = residual = None
    for k, (name, wkw) in enumerate(wrappers):
        if name == BATCHED_WRAPPERS[0]:
            if residual is not None:
                raise ConfigError("AlignmentReward must come before ResidualLCWrapper")
            reward = dict(wkw)
        elif name == BATCHED_WRAPPERS[1]:
            if k != len(wrappers) - 1:
                raise ConfigError("ResidualLCWrapper must be the outermost wrapper")
            residual = dict(wkw)
        else:
            raise ConfigError(
                f"env_wrapper {name!r} has no batched form (batched: "
                f"{', '.join(BATCHED_WRAPPERS)}); use --vec-env subproc or dummy"
            )
    env = BatchedVecEnv(venv, reward, residual)
    if seed is not None:
        env.seed(seed)
    return env


# ---------------------------------------------------------------------------------- helpers
def _residual_spec(base: Any, kwargs: dict[str, Any]) -> ResidualSpec:
    """``ResidualLCWrapper``'s spec for a session like ``base`` (its checks included)."""
    kw = dict(kwargs)
    mode = kw.pop("choice_mode", None)
    if mode is not None and mode != base.choice_mode:
        raise ConfigError(
            f"ResidualLCWrapper: choice_mode={mode!r} but the env uses {base.choice_mode!r} "
            "(pass the same choice_mode in env_kwargs)"
        )
    allowed = {
        "pace_scale",
        "choice_scale",
        "audio_scale",
        "terminal",
        "k_em",
        "gate_em",
        "deadband",
    }
    unknown = sorted(set(kw) - allowed)
    if unknown:
        raise ConfigError(f"ResidualLCWrapper: unknown argument(s) {', '.join(unknown)}")
    audio = kw.get("audio_scale")
    return ResidualSpec(
        choice_mode=base.choice_mode,
        max_children=int(base.max_children),
        pace_scale=float(kw.get("pace_scale", 0.3)),
        choice_scale=float(kw.get("choice_scale", 0.5)),
        audio_scale=None if audio is None else float(audio),
        decision_hz=int(base.decision_hz),
        terminal=float(kw.get("terminal", 0.0)),
        k_em=float(kw.get("k_em", 0.0)),
        gate_em=float(kw.get("gate_em", 0.0)),
        deadband=float(kw.get("deadband", 0.0)),
    )


def _pick(infos: dict[str, Any], final: dict[str, Any], key: str, done: np.ndarray) -> np.ndarray:
    """The step's float values of ``key``: the final info's where the episode ended."""
    out = np.array(infos[key], dtype=np.float64) if key in infos else np.full(done.size, math.nan)
    if done.any() and key in final:
        out[done] = final[key][done]
    if key in infos and f"_{key}" in infos:  # keys the step did not give read NaN
        out[~infos[f"_{key}"] & ~done] = math.nan
    return out


def _pick_flag(
    infos: dict[str, Any], final: dict[str, Any], key: str, done: np.ndarray
) -> np.ndarray:
    out = np.array(infos[key], dtype=bool)
    if done.any():
        out[done] = final[key][done]
    return out


def _value(final: dict[str, Any], key: str, i: int) -> Any:
    arr, mask = final[key], final.get(f"_{key}")
    if mask is not None and not mask[i]:
        return None
    v = arr[i]
    return float(v) if isinstance(v, np.floating) else v
