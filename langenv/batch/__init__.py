"""``LangCtrl-v0`` natively vectorised (Gymnasium's ``vector_entry_point``): N sessions stepped in
one compiled call per decision, spread over the cores.

    import gymnasium as gym
    import langenv  # noqa: F401

    envs = gym.make_vec("LangCtrl-v0", num_envs=32, vectorization_mode="vector_entry_point")

:class:`LangCtrlVectorEnv` is the env (its docstring: seeding, autoreset, infos);
:mod:`langenv.batch.kernels` its compiled rounds.
"""

from __future__ import annotations

from langenv.batch.env import PARALLEL_MODES, LangCtrlVectorEnv, make_vector_env

__all__ = ["PARALLEL_MODES", "LangCtrlVectorEnv", "make_vector_env"]
