"""Widening a saved model to graphs with more choices (train/widen.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from langenv.errors import ConfigError
from langenv.task import observation as ob
from policies.learned import PPOPolicy, observation_layout
from train.widen import main, widen

SHIPPED = Path(__file__).resolve().parents[1] / "models" / "ppo_aligner.zip"  # 6 choices


def _mean_action(policy: PPOPolicy, x: np.ndarray) -> np.ndarray:
    return policy.model(policy.normalizer.normalize_obs(x[None, :].astype(np.float32))[0])


def test_widened_model_acts_as_the_original_whatever_the_new_inputs(tmp_path: Path) -> None:
    out = widen(SHIPPED, 9, tmp_path / "wide")
    old, new = PPOPolicy.load(SHIPPED), PPOPolicy.load(out)
    at = ob.FIRST_CHILD + ob.CHILD_FIELDS * 6
    assert new.model.n_inputs == old.model.n_inputs + 3 * ob.CHILD_FIELDS == 52
    rng = np.random.default_rng(0)
    for _ in range(20):
        x = rng.uniform(-1.0, 1.0, old.model.n_inputs)
        extra = rng.uniform(-1.0, 1.0, 3 * ob.CHILD_FIELDS)
        wide = np.concatenate([x[:at], extra, x[at:]])
        np.testing.assert_allclose(_mean_action(new, wide), _mean_action(old, x), atol=1e-12)
    config = yaml.safe_load((tmp_path / "wide_config.yaml").read_text())
    assert config["residual"]["max_children"] == 9
    assert config["observation_layout"] == observation_layout(9)
    assert config["widened_from"]["max_children"] == 6
    assert new.trained_graph == old.trained_graph == "study"  # widening trains on nothing new


def test_widen_refuses_bad_requests(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="must exceed 6"):
        widen(SHIPPED, 6, tmp_path / "same")
    with pytest.raises(FileNotFoundError, match="nothing"):
        widen(tmp_path / "nothing.zip", 9, tmp_path / "x")
    (tmp_path / "taken.zip").write_bytes(b"")
    assert main([str(SHIPPED), "--max-children", "9", "--out", str(tmp_path / "taken")]) == 2
    assert not (tmp_path / "same.zip").exists()
