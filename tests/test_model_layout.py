"""A learned model records the code and the observation layout it was trained with, and refuses
to run on another layout with a named error."""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
import yaml

from langenv.errors import ModelError, ObservationLayoutError
from policies.learned import FEATURES, PPOPolicy, model_files, observation_layout

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "models" / "ppo_aligner.zip"


def _copy_model(src: Path, dst_dir: Path) -> Path:
    for f in model_files(src):
        shutil.copy(f, dst_dir / f.name)
    return dst_dir / src.name


def test_layout_signature_names_fields_and_scales() -> None:
    six, nine = observation_layout(6), observation_layout(9)
    assert six["size"] == 16 + 3 * 6 + len(FEATURES)
    assert nine["size"] == six["size"] + 9
    assert six["signature"] != nine["signature"]
    assert observation_layout(6) == six  # deterministic


def test_shipped_model_without_signature_still_loads() -> None:
    cfg = yaml.safe_load(model_files(SHIPPED)[2].read_text())
    assert "observation_layout" not in cfg  # trained before the signature existed
    policy = PPOPolicy.load(SHIPPED)
    assert policy.model.n_inputs == observation_layout(6)["size"]


def test_size_mismatch_without_signature_is_a_named_error(tmp_path: Path) -> None:
    model = _copy_model(SHIPPED, tmp_path)
    cfg_path = model_files(model)[2]
    cfg = yaml.safe_load(cfg_path.read_text())
    cfg["residual"]["max_children"] = 9  # as if the graph now had nine choices
    cfg_path.write_text(yaml.safe_dump(cfg))
    with pytest.raises(ObservationLayoutError) as err:
        PPOPolicy.load(model)
    msg = str(err.value)
    assert model.name in msg and "size=52" in msg and "size=43" in msg
    assert isinstance(err.value, ModelError) and isinstance(err.value, ValueError)


def test_recorded_signature_mismatch_is_a_named_error(tmp_path: Path) -> None:
    model = _copy_model(SHIPPED, tmp_path)
    cfg_path = model_files(model)[2]
    cfg = yaml.safe_load(cfg_path.read_text())
    cfg["observation_layout"] = {"size": 43, "signature": "0123456789abcdef"}
    cfg_path.write_text(yaml.safe_dump(cfg))
    with pytest.raises(ObservationLayoutError, match="0123456789abcdef") as err:
        PPOPolicy.load(model)
    assert err.value.expected == f"size=43 signature={observation_layout(6)['signature']}"
    assert cfg_path.name in str(err.value)


def test_model_on_a_graph_with_more_choices_fails_at_its_first_observation() -> None:
    policy = PPOPolicy.load(SHIPPED)
    policy.reset()
    with pytest.raises(ObservationLayoutError, match="size=52"):
        policy.act(np.zeros(16 + 3 * 9, np.float32))


def test_trained_model_records_code_version_and_layout(tiny_ppo_models: tuple[Path, ...]) -> None:
    import langenv

    cfg = yaml.safe_load(model_files(tiny_ppo_models[0])[2].read_text())
    source = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert cfg["versions"]["langctrl"] == source
    assert langenv.__version__ == source  # the installed metadata is not stale
    assert cfg["observation_layout"] == observation_layout(cfg["residual"]["max_children"])
    PPOPolicy.load(tiny_ppo_models[0])  # and it loads


def test_stale_metadata_records_the_source_version(capsys: pytest.CaptureFixture[str]) -> None:
    from train.provenance import code_version

    source = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    out = code_version("0.0.1")
    assert out["langctrl"] == source
    assert "reinstall" in capsys.readouterr().err
