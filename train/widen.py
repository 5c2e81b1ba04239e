"""Widen a saved model to phrase graphs with more choices, acting exactly as before.

Run::

    langctrl widen models/ppo_aligner.zip --max-children 9 --out runs/widened/ppo_aligner9
    langctrl train --config configs/ppo_general.yaml --init-from runs/widened/ppo_aligner9.zip

The learned policy's input holds one block of ``langenv.task.observation.CHILD_FIELDS`` inputs per
choice of the graph's largest out-degree (``max_children``), so a model trained on a graph with 6
choices cannot read an exercise script with 9, nor be fine-tuned on one (``--init-from`` needs
the same spaces). The widened model has the new child blocks inserted after the old ones, with
zero weights into both first layers (actor and critic) and neutral normalisation statistics
(mean 0, variance 1): its actions and values are the original's (to rounding) for any values of
the new inputs, and fine-tuning can learn to read them. Writes ``OUT.zip``,
``OUT_vecnormalize.pkl`` and ``OUT_config.yaml``, whose ``residual.max_children`` and
``observation_layout`` are the new ones, whose training graph records stay the source's (the
widened model was trained on nothing new) and whose ``widened_from`` records the source (file
name, SHA-256, ``max_children``). Like any learned policy it speaks the exercise's phrase graph
(:mod:`langenv.exercise.script`). The result is loaded once with
:meth:`policies.learned.PPOPolicy.load`.

Evaluating a ``"target"`` model on a graph with more choices needs no file:
:meth:`policies.learned.PPOPolicy.use_graph` widens it in memory the same way.
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np
import yaml

__all__ = ["widen"]

_FIRST_LAYERS = ("mlp_extractor.policy_net.0.weight", "mlp_extractor.value_net.0.weight")


def widen(src: Path, max_children: int, out: Path) -> Path:
    """Write the widened copy of model ``src`` (module docstring); returns ``OUT.zip``.

    Args:
        src: A model zip (``STEM.zip`` with ``STEM_vecnormalize.pkl``, ``STEM_config.yaml``).
        max_children: The new largest number of choices, > the model's.
        out: Stem of the widened model.

    Raises:
        FileNotFoundError: naming a missing input file.
        FileExistsError: if ``OUT.zip`` exists.
        ConfigError: (a ValueError) if ``max_children`` is not larger than the model's, or the
            model's network is not the separate actor/critic MLP this reads.
    """
    from stable_baselines3 import PPO

    from langenv.errors import ConfigError
    from policies.learned import file_sha256, model_files, observation_layout, widened_inputs

    zip_in, pkl_in, cfg_in = model_files(src)
    zip_out, pkl_out, cfg_out = model_files(out)
    for f in (zip_in, pkl_in, cfg_in):
        if not f.is_file():
            raise FileNotFoundError(f"langctrl widen: not found: {f}")
    if zip_out.exists():
        raise FileExistsError(f"langctrl widen: {zip_out} exists")
    config = yaml.safe_load(cfg_in.read_text())
    old_k = int(config["residual"]["max_children"])
    if max_children <= old_k:
        raise ConfigError(f"langctrl widen: --max-children {max_children} must exceed {old_k}")
    model = PPO.load(zip_in, device="cpu")
    n_old = int(np.prod(model.observation_space.shape or (0,)))
    intents = bool(config["residual"].get("child_intents", False))
    grown = widened_inputs(old_k, max_children, intents)  # where the new inputs go, last first
    space = _box(n_old + sum(n for _, n in grown))
    state = model.policy.state_dict()
    for key in _FIRST_LAYERS:
        if key not in state or tuple(state[key].shape[1:]) != (n_old,):
            raise ConfigError(f"langctrl widen: {zip_in}: no first layer {key} of {n_old} inputs")
        for at, n_new in grown:
            state[key] = _insert_columns(state[key], at, n_new)
    policy = type(model.policy)(space, model.action_space, model.lr_schedule, **model.policy_kwargs)
    policy.load_state_dict(state)
    model.policy, model.observation_space = policy, space
    norm = _widen_normalizer(pkl_in, space, model.action_space, grown)
    zip_out.parent.mkdir(parents=True, exist_ok=True)
    model.save(zip_out)
    norm.save(pkl_out)
    config["residual"]["max_children"] = max_children
    config["observation_layout"] = observation_layout(max_children, intents)
    config["widened_from"] = {
        "model": zip_in.name,
        "sha256": file_sha256(zip_in),
        "max_children": old_k,
    }
    cfg_out.write_text(yaml.safe_dump(config, sort_keys=False))
    from policies.learned import PPOPolicy

    PPOPolicy.load(zip_out)
    return zip_out


def _box(n: int) -> Any:
    import gymnasium as gym

    return gym.spaces.Box(-1.0, 1.0, (n,), np.float32)


def _insert_columns(weight: Any, at: int, n: int) -> Any:
    """``weight`` ``(out, in)`` with ``n`` zero columns inserted before column ``at``."""
    import torch

    zeros = torch.zeros(weight.shape[0], n, dtype=weight.dtype)
    return torch.cat([weight[:, :at], zeros, weight[:, at:]], dim=1)


def _widen_normalizer(
    src: Path, space: Any, actions: Any, grown: tuple[tuple[int, int], ...]
) -> Any:
    """The ``VecNormalize`` of ``src`` with ``n`` neutral inputs (mean 0, variance 1) inserted
    before input ``at`` for each ``(at, n)`` of ``grown`` (in its order), attached to a bare env
    of the widened spaces so that it can be saved."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv

    class Spaces(gym.Env[np.ndarray, np.ndarray]):  # never reset nor stepped
        observation_space, action_space = space, actions

    with src.open("rb") as fh:
        norm = pickle.load(fh)
    rms = norm.obs_rms
    for at, n in grown:
        rms.mean = np.insert(np.asarray(rms.mean, np.float64), at, np.zeros(n))
        rms.var = np.insert(np.asarray(rms.var, np.float64), at, np.ones(n))
    norm.observation_space = space
    norm.set_venv(DummyVecEnv([Spaces]))
    return norm
