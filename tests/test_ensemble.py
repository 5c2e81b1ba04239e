"""Ensembles of learned aligners (policies/ensemble.py) and their manifests (train/ensemble.py)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

import langenv
from eval.compare import policy_names
from langctrl.jobs.ensemble import main as ensemble_main
from langenv.exercise import speak
from policies import load_policy
from policies.ensemble import PPOEnsemble, write_manifest
from policies.learned import PPOPolicy, model_files


@pytest.fixture
def members(tiny_ppo_models: tuple[Path, ...], tmp_path: Path) -> list[Path]:
    """Two members (distinct seeds) copied into this test's folder, where a manifest may go."""
    return [_copy(m, tmp_path, stem) for m, stem in zip(tiny_ppo_models, "ab", strict=True)]


@pytest.fixture
def manifest(members: list[Path], tmp_path: Path) -> Path:
    return write_manifest(tmp_path / "ensemble.yaml", members)


def _copy(model: Path, folder: Path, stem: str) -> Path:
    targets = model_files(folder / stem)
    for src, dst in zip(model_files(model), targets, strict=True):
        shutil.copy(src, dst)
    return targets[0]


def _env(policy: Any) -> Any:
    return gym.make(
        langenv.ENV_ID,
        phrase_graph=speak(policy).ref,  # the study's exercise's graph; fits the members to it
        decision_hz=policy.decision_hz,
        max_episode_steps=60 * policy.decision_hz,
        **policy.env_kwargs,
    )


def test_ensemble_loads_with_distinct_members(manifest: Path) -> None:
    ens = load_policy(f"ppo:{manifest}")
    assert isinstance(ens, PPOEnsemble) and len(ens.members) >= 2
    weights = [m.model.weights[-1] for m in ens.members]
    assert not np.array_equal(weights[0], weights[1])
    assert ens.decision_hz == ens.members[0].decision_hz == 25
    assert ens.members[0].residual.spec.terminal > 0.0


def test_ensemble_applies_the_mean_correction(manifest: Path, members: list[Path]) -> None:
    """Step by step, the ensemble's action is the residual map of its members' mean correction."""
    ens = PPOEnsemble.load(manifest)
    solo = [PPOPolicy.load(p) for p in members]  # independent copies, fed the same history
    env = _env(ens)
    obs, _ = env.reset(seed=3)
    ens.reset()
    for s in solo:
        s.reset()
    for _ in range(60):
        act = ens.act(obs)
        r = np.mean([s.correction(obs) for s in solo], axis=0)
        wants = [s.residual.action(r) for s in solo]  # every copy records r as applied
        want = wants[0]
        np.testing.assert_allclose(act, want, atol=1e-6)
        assert env.action_space.contains(act)
        obs, _, term, trunc, _ = env.step(act)
        if term or trunc:
            break


def test_one_member_ensemble_is_that_member(members: list[Path], tmp_path: Path) -> None:
    model = members[0]
    manifest = write_manifest(tmp_path / "one.yaml", [model])
    ens, solo = PPOEnsemble.load(manifest), PPOPolicy.load(model)
    env = _env(solo)
    obs, _ = env.reset(seed=4)
    ens.reset()
    solo.reset()
    for _ in range(40):
        a, b = ens.act(obs), solo.act(obs)
        assert np.array_equal(a, b)
        obs, *_ = env.step(a)


def test_manifest_errors_name_the_file(members: list[Path], tmp_path: Path) -> None:
    a, b = members
    manifest = write_manifest(tmp_path / "e.yaml", [a, b])
    data = yaml.safe_load(manifest.read_text())

    with pytest.raises(FileNotFoundError, match=r"missing\.yaml"):
        PPOEnsemble.load(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    for text, match in (
        ("kind: something-else\nmembers: []\n", "kind"),
        ("kind: ppo-ensemble\nmembers: []\n", "members"),
        ("kind: ppo-ensemble\nmembers: [{sha256: x}]\n", r"members\[0\]"),
        ("kind: [unclosed\n", "cannot read"),
    ):
        bad.write_text(text)
        with pytest.raises(ValueError, match=match):
            PPOEnsemble.load(bad)
        with pytest.raises(ValueError, match=r"bad\.yaml"):
            load_policy(f"ppo:{bad}")

    b.write_bytes(a.read_bytes())  # a member changed since the manifest was written
    with pytest.raises(ValueError, match=r"b\.zip.*sha256"):
        PPOEnsemble.load(manifest)
    b.unlink()
    with pytest.raises(FileNotFoundError, match=r"b\.zip"):
        PPOEnsemble.load(manifest)
    assert data["kind"] == "ppo-ensemble"


def test_members_must_share_their_design(members: list[Path], tmp_path: Path) -> None:
    a, b = members
    cfg = model_files(b)[2]
    config = yaml.safe_load(cfg.read_text())
    config["residual"]["terminal"] = 0.0
    cfg.write_text(yaml.safe_dump(config))
    with pytest.raises(ValueError, match="residual design"):
        write_manifest(tmp_path / "e.yaml", [a, b])
    assert not (tmp_path / "e.yaml").exists() and not (tmp_path / "e.yaml.tmp").exists()


def test_cli_writes_a_manifest_and_reports_errors(
    members: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = members
    assert ensemble_main([str(a), str(b), "--out", str(tmp_path / "e.yaml")]) == 0
    assert len(PPOEnsemble.load(tmp_path / "e.yaml").members) == 2
    elsewhere = tmp_path / "sub" / "e.yaml"
    elsewhere.parent.mkdir()
    assert ensemble_main([str(a), "--out", str(elsewhere)]) == 2
    assert "manifest's folder" in capsys.readouterr().err and not elsewhere.exists()
    assert ensemble_main([str(tmp_path / "nope.zip"), "--out", str(tmp_path / "f.yaml")]) == 2
    assert "nope.zip" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        ensemble_main([str(a), "--out", str(tmp_path / "e.txt")])


def test_compare_names_manifests_by_stem() -> None:
    names = policy_names(["lc", "ppo:models/a.yaml", "ppo:models/b.zip"])
    assert names == {"lc": "lc", "ppo:models/a.yaml": "ppo-a", "ppo:models/b.zip": "ppo-b"}
