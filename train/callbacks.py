"""The callbacks of a training run, beside SB3's ``CheckpointCallback`` (as rl-zoo3 keeps its own
in ``callbacks.py``).

* :class:`MetricsEvalCallback`: SB3's periodic evaluation on the held-out users, also recording
  the alignment and speech metrics (:data:`EVAL_METRICS`) that ``train.export --best`` chooses a
  checkpoint by, and (a phrase chooser's run) the base's own figures once (:data:`BASE_FILE`);
  :func:`restore_history` hands a resumed run's callback the evaluations made so far.
* :class:`SaveBest`: the model at the highest mean evaluation return (:data:`BEST_RETURN`).
* :class:`ResumePointCallback`: the resume point after every update
  (:func:`train.resume.save_resume_point`).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3.common.callbacks import BaseCallback, EvalCallback

from train.factories import env_has_attr
from train.resume import save_resume_point, save_triple

__all__ = [
    "BASE_FILE",
    "BEST_RETURN",
    "EVAL_METRICS",
    "MetricsEvalCallback",
    "ResumePointCallback",
    "SaveBest",
    "restore_history",
]

BEST_RETURN = "best_return"
"""The run's folder of the model at its highest mean evaluation return (SB3's best model)."""

EVAL_METRICS: tuple[str, ...] = (
    "abs_am", "em_mean_abs", "a_dev", "content_share", "voice_natural", "legs_in_step"
)  # fmt: skip


#: The base's figures on the held-out users (``eval/`` of a run; :data:`EVAL_METRICS`, one per
#: user): a phrase chooser's run evaluates its base once, before training.
BASE_FILE = "base.npz"


def _is_chooser(env: Any) -> bool:
    """Whether ``env`` (a VecEnv) is a phrase chooser's (``decisions: choices``)."""
    if not env_has_attr(env, "residual_spec"):
        return False
    spec = env.get_attr("residual_spec", indices=[0])[0]
    return getattr(spec, "decisions", "steps") == "choices"


def _nanmean(values: Sequence[float]) -> float:
    """The mean of the finite values (NaN when there are none)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.mean(x)) if x.size else math.nan


class _ZeroCorrection:
    """A "model" whose action is always 0: the residual's base (for ``evaluate_policy``)."""

    def __init__(self, shape: tuple[int, ...] | None) -> None:
        self.shape = tuple(shape or ())

    def predict(self, observation: Any, *args: Any, **kwargs: Any) -> tuple[np.ndarray, None]:
        n = int(np.shape(observation)[0])
        return np.zeros((n, *self.shape), np.float32), None


class MetricsEvalCallback(EvalCallback):
    """EvalCallback that also logs and records the held-out users' ``|AM|``, ``|EM|`` and
    ``|a - 1|`` (:data:`EVAL_METRICS`), so that a checkpoint can be chosen by them
    (``python -m train.export RUN --best``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._episode: dict[str, list[float]] = {k: [] for k in EVAL_METRICS}
        self._em_steps: list[float] = []
        self._a_steps: list[float] = []
        self.evaluations_metrics: dict[str, list[list[float]]] = {k: [] for k in EVAL_METRICS}

    def _on_training_start(self) -> None:
        """Evaluate the base (a zero correction) once on the held-out users, where the env
        reports the speech people hear: ``eval/base.npz``, what ``train.export --best`` holds
        the checkpoints against (:data:`BASE_FILE`)."""
        super()._on_training_start()
        if self.log_path is None:
            return
        path = Path(self.log_path).parent / BASE_FILE
        if path.is_file() or not _is_chooser(self.eval_env):
            return
        self._episode = {k: [] for k in EVAL_METRICS}
        self._em_steps, self._a_steps = [], []
        from stable_baselines3.common.evaluation import evaluate_policy

        evaluate_policy(
            _ZeroCorrection(self.eval_env.action_space.shape),
            self.eval_env,
            n_eval_episodes=self.n_eval_episodes,
            deterministic=True,
            callback=self._log_success_callback,
        )
        if np.isfinite(self._episode["content_share"]).all():
            arrays: dict[str, Any] = {k: np.asarray(v, float) for k, v in self._episode.items()}
            np.savez(path, **arrays)
            print(
                f"[eval of the base] held-out users: content "
                f"{np.mean(self._episode['content_share']):.4f}, voice natural "
                f"{np.mean(self._episode['voice_natural']):.4f}, |AM| <= 1 s "
                f"{np.mean(np.asarray(self._episode['abs_am']) <= 1.0):.3f}, legs in step "
                f"{_nanmean(self._episode['legs_in_step']):.3f}",
                file=sys.stderr,
            )

    def _on_step(self) -> bool:
        self._episode = {k: [] for k in EVAL_METRICS}
        self._em_steps, self._a_steps = [], []
        ok = bool(super()._on_step())
        if self._episode["abs_am"]:
            for key in EVAL_METRICS:
                self.evaluations_metrics[key].append(list(self._episode[key]))
            self._save_metrics()
            am = float(np.nanmean(self._episode["abs_am"]))
            em = float(np.mean(self._episode["em_mean_abs"]))
            a_dev = float(np.nanmean(self._episode["a_dev"]))
            self.logger.record("eval/abs_am", am)
            self.logger.record("eval/abs_am_median", float(np.nanmedian(self._episode["abs_am"])))
            self.logger.record("eval/em_mean_abs", em)
            self.logger.record("eval/a_dev", a_dev)
            speech = ""
            if np.isfinite(self._episode["content_share"]).any():
                content = float(np.nanmean(self._episode["content_share"]))
                voice = float(np.nanmean(self._episode["voice_natural"]))
                within = float(np.mean(np.asarray(self._episode["abs_am"]) <= 1.0))
                self.logger.record("eval/content_share", content)
                self.logger.record("eval/voice_natural", voice)
                legs = _nanmean(self._episode["legs_in_step"])
                self.logger.record("eval/legs_in_step", legs)
                speech = (
                    f", content {content:.4f}, voice natural {voice:.4f}, |AM| <= 1 s {within:.3f}"
                    f", legs in step {legs:.3f}"
                )
            print(
                f"[eval @ {self.num_timesteps} steps] held-out users: mean |AM| {am:.3f} s, "
                f"median |AM| {np.nanmedian(self._episode['abs_am']):.3f} s, mean |EM| "
                f"{em:.3f} s, mean |a-1| {a_dev:.3f}{speech}, return {self.last_mean_reward:.2f}",
                file=sys.stderr,
            )
        return ok

    def _save_metrics(self) -> None:
        """Rewrite ``evaluations.npz`` with SB3's arrays and :data:`EVAL_METRICS`."""
        if self.log_path is None or len(self.evaluations_timesteps) != len(
            self.evaluations_metrics["abs_am"]
        ):
            return
        arrays: dict[str, Any] = {
            "timesteps": self.evaluations_timesteps,
            "results": self.evaluations_results,
            "ep_lengths": self.evaluations_length,
        }
        arrays.update({k: np.asarray(v, dtype=float) for k, v in self.evaluations_metrics.items()})
        np.savez(self.log_path, **arrays)

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        info = locals_["info"]
        self._em_steps.append(abs(float(info.get("em", 0.0))))
        if not info.get("speech_done", False):
            self._a_steps.append(abs(float(info.get("a", 1.0)) - 1.0))
        if locals_["done"]:
            am = info.get("am")
            self._episode["abs_am"].append(abs(float(am)) if am is not None else math.nan)
            em = info.get("em_mean_abs")  # the session's own, where the env reports it
            em = float(em) if em is not None else float(np.mean(self._em_steps))
            self._episode["em_mean_abs"].append(em)
            a_dev = float(np.mean(self._a_steps)) if self._a_steps else math.nan
            self._episode["a_dev"].append(a_dev)
            for key in ("content_share", "voice_natural", "legs_in_step"):
                value = info.get(key)
                self._episode[key].append(float(value) if value is not None else math.nan)
            self._em_steps, self._a_steps = [], []


def restore_history(eval_cb: EvalCallback, eval_dir: Path, best_cfg: Path, steps: int) -> int:
    """Give a resumed run's evaluation callback the evaluations made up to ``steps`` and the best
    mean return so far; returns how many evaluations carried over."""
    path = eval_dir / "evaluations.npz"
    if path.is_file():
        with np.load(path) as data:
            keep = np.asarray(data["timesteps"]) <= steps
            eval_cb.evaluations_timesteps = [int(t) for t in np.asarray(data["timesteps"])[keep]]
            eval_cb.evaluations_results = [list(r) for r in np.asarray(data["results"])[keep]]
            eval_cb.evaluations_length = [list(r) for r in np.asarray(data["ep_lengths"])[keep]]
            if isinstance(eval_cb, MetricsEvalCallback):
                width = np.asarray(data["results"]).reshape(keep.size, -1).shape[1]
                for key in EVAL_METRICS:  # NaN (one per user) for a run recorded before they were
                    missing = np.full((keep.size, width), np.nan)
                    rows = np.asarray(data[key]) if key in data else missing
                    kept = rows[keep]
                    eval_cb.evaluations_metrics[key] = [np.atleast_1d(r).tolist() for r in kept]
    means = [float(np.mean(r)) for r in eval_cb.evaluations_results]
    best = max(means, default=-np.inf)
    if best_cfg.is_file():
        recorded = (yaml.safe_load(best_cfg.read_text()) or {}).get("eval_mean_reward")
        if isinstance(recorded, int | float):
            best = max(best, float(recorded))
    eval_cb.best_mean_reward = best
    if means:
        eval_cb.last_mean_reward = means[-1]
    return len(means)


class ResumePointCallback(BaseCallback):
    """Saves the resume point at the start of every rollout, i.e. right after PPO has learned
    from the previous one, and once more at the end of training."""

    def __init__(self, ckpt_dir: Path, name: str) -> None:
        super().__init__()
        self.ckpt_dir, self.name = ckpt_dir, name
        self.saved_at: int | None = None

    def _save(self) -> None:
        save_resume_point(self.model, self.ckpt_dir, self.name)
        self.saved_at = int(self.model.num_timesteps)

    def _on_rollout_start(self) -> None:
        self._save()

    def _on_training_end(self) -> None:
        self._save()

    def _on_step(self) -> bool:
        return True


class SaveBest(BaseCallback):
    """Called by the evaluation (its ``callback_on_new_best``) at a new best mean return: saves
    the model, its normalisation and ``config`` with ``eval_mean_reward`` at ``stem``."""

    def __init__(self, stem: Path, config: dict[str, Any]) -> None:
        super().__init__()
        self.stem, self.config = stem, config

    def _on_step(self) -> bool:
        evaluation = self.parent
        assert isinstance(evaluation, EvalCallback)
        cfg = dict(self.config, eval_mean_reward=float(evaluation.best_mean_reward))
        save_triple(self.model, None, self.stem, cfg)
        return True
