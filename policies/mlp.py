"""The deterministic actor of an SB3 ``MlpPolicy``, evaluated with NumPy (a learned policy's
network, :class:`policies.learned.PPOPolicy`)."""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

__all__ = ["MlpActor"]


@dataclass(frozen=True)
class MlpActor:
    """The deterministic actor of an SB3 ``MlpPolicy`` (mean action), evaluated with NumPy.

    Reading the weights and running the small MLP in NumPy keeps torch's thread pools out of the
    evaluation, whose worker processes are forked (torch in a forked child can deadlock).

    Attributes:
        weights: Weight matrices ``(out, in)`` of the hidden layers, then of the action layer.
        biases: Their biases ``(out,)``.
        activation: ``"tanh"`` or ``"relu"`` (hidden layers).
    """

    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    activation: Literal["tanh", "relu"] = "tanh"

    @property
    def n_inputs(self) -> int:
        """Observation size."""
        return int(self.weights[0].shape[1])

    @property
    def n_actions(self) -> int:
        """Action size."""
        return int(self.weights[-1].shape[0])

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Mean action for one normalised observation ``(n_inputs,)``, clipped to [-1, 1]."""
        # Row sums (NumPy's pairwise sums) and the C library's tanh, not BLAS's gemv and NumPy's
        # vectorised tanh, whose results depend on the CPU: the same actions on any machine.
        h = np.asarray(obs, dtype=np.float64).reshape(-1)
        for w, b in zip(self.weights[:-1], self.biases[:-1], strict=True):
            h = np.sum(w * h, axis=1) + b
            if self.activation == "tanh":
                h = np.array([math.tanh(v) for v in h.tolist()])
            else:
                h = np.maximum(h, 0.0)
        out = np.sum(self.weights[-1] * h, axis=1) + self.biases[-1]
        return np.clip(out, -1.0, 1.0)

    @classmethod
    def from_sb3_zip(cls, path: Path) -> MlpActor:
        """Read the actor of a PPO ``MlpPolicy`` saved by SB3 (``model.save``).

        Raises:
            ValueError: if the zip is not such a model.
            zipfile.BadZipFile: if it is not a zip at all.
        """
        import io
        import json

        import torch

        with zipfile.ZipFile(path) as zf:
            data = json.loads(zf.read("data"))
            state = torch.load(
                io.BytesIO(zf.read("policy.pth")), map_location="cpu", weights_only=True
            )
        act_repr = str((data.get("policy_kwargs") or {}).get("activation_fn", "Tanh"))
        if "Tanh" in act_repr:
            activation: Literal["tanh", "relu"] = "tanh"
        elif "ReLU" in act_repr:
            activation = "relu"
        else:
            raise ValueError(f"unsupported activation {act_repr}")
        prefix = "mlp_extractor.policy_net."
        layers = sorted(
            {int(k[len(prefix) :].split(".")[0]) for k in state if k.startswith(prefix)}
        )
        weights = [state[f"{prefix}{i}.weight"] for i in layers] + [state["action_net.weight"]]
        biases = [state[f"{prefix}{i}.bias"] for i in layers] + [state["action_net.bias"]]
        return cls(
            tuple(w.detach().numpy().astype(np.float64) for w in weights),
            tuple(b.detach().numpy().astype(np.float64) for b in biases),
            activation,
        )
