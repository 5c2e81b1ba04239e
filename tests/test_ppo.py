"""Smoke test of the training script (python -m train.ppo) and its config handling."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import langenv
from langenv.errors import ConfigError
from langenv.exercise import speak
from policies.analytic import LanguageController
from policies.learned import PPOPolicy, file_sha256, model_files
from train.config import TrainArgs, _policy_kwargs, _schedule, load_config
from train.factories import use_subprocesses
from train.ppo import parse_args
from train.resume import checkpoint_files

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "configs" / "ppo.yaml"
TWO_ENVS = REPO / "configs" / "ppo_2env.yaml"
"""The recipe batched as 2 envs of 1024-step rollouts: the runs below count on 2048-step
rollouts with --n-envs 2 (checkpoints, evaluations and resume points at 2048 and 4096 steps)."""


def _finetune_config(tmp: Path) -> Path:
    """A choice-only fine-tune of the recipe (pace corrections off), as a user writes one."""
    path = tmp / "finetune.yaml"
    residual = (
        "{pace_scale: 0.0, audio_scale: 0.0, choice_scale: 0.5, choice_mode: target,"
        " terminal: 1.0, k_em: 1.0}"
    )
    path.write_text(
        f"inherit: {CONFIG}\n"
        "LangCtrl-v0:\n"
        "  learning_rate: !!float 1e-4\n"
        "  env_wrapper:\n"
        "    - train.wrappers.AlignmentReward: {w_em: 3.0, w_adev: 2.0, w_am_fine: 2.0}\n"
        f"    - train.wrappers.ResidualLCWrapper: {residual}\n"
        "train:\n"
        "  name: ppo_finetune\n"
    )
    return path


def _train(*extra: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    cmd = [sys.executable, "-m", "train.ppo", "--config", str(TWO_ENVS), "--no-progress-bar"]
    return subprocess.run(
        [*cmd, *extra], cwd=REPO, env=env, capture_output=True, text=True, timeout=300
    )


@dataclass(frozen=True)
class SmokeRun:
    """A tiny run of the real script (2 048 steps, one evaluation), resumed to 4 096 steps."""

    out: Path
    first: subprocess.CompletedProcess[str]
    resumed: subprocess.CompletedProcess[str]

    @property
    def checkpoints(self) -> Path:
        return self.out / "checkpoints"


# The tests of the smoke run share one worker (xdist_group; pyproject: --dist loadgroup), so the
# run is trained once.
@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory: pytest.TempPathFactory) -> SmokeRun:
    out = tmp_path_factory.mktemp("smoke") / "run"
    common = ["--out", str(out), "--n-envs", "2", "--eval-freq", "2048", "--checkpoint-freq"]
    first = _train(*common, "2048", "--total-timesteps", "2048", "--n-eval-episodes", "1")
    assert first.returncode == 0, first.stderr[-3000:]
    resumed = _train(
        *common, "2048", "--total-timesteps", "4096", "--n-eval-episodes", "0", "--resume"
    )
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    return SmokeRun(out, first, resumed)


def _policy_env(policy: PPOPolicy) -> Any:
    import gymnasium as gym

    return gym.make(
        langenv.ENV_ID,
        phrase_graph=speak(policy).ref,  # fits the model to the graph: before env_kwargs
        decision_hz=policy.decision_hz,
        **policy.env_kwargs,
    )


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_run_writes_model_checkpoints_logs_and_config(smoke_run: SmokeRun) -> None:
    out = smoke_run.out
    zip_path, norm_path, cfg_path = model_files(out / "ppo_langctrl.zip")
    assert zip_path.is_file() and norm_path.is_file() and cfg_path.is_file()
    assert (smoke_run.checkpoints / "ppo_langctrl_2048_steps.zip").is_file()
    assert any((out / "tb").iterdir())
    assert (out / "eval" / "evaluations.npz").is_file()
    assert (out / "best_return" / "ppo_langctrl.zip").is_file()  # SB3's highest return
    assert not (out / "best").exists()  # "best" is export --best's: runs/NAME/best.zip
    cfg = yaml.safe_load(cfg_path.read_text())
    assert cfg["train"]["seed"] >= 1_000_000
    assert cfg["residual"]["choice_mode"] == cfg["env_kwargs"]["choice_mode"]


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_periodic_evaluation_records_the_metrics_and_best_exports_it(
    smoke_run: SmokeRun, tmp_path: Path
) -> None:
    """evaluations.npz holds each user's |AM|, |EM| and |a-1|; --best exports that checkpoint."""
    from train.callbacks import EVAL_METRICS
    from train.export import main as export_main

    with np.load(smoke_run.out / "eval" / "evaluations.npz") as data:
        assert list(data["timesteps"]) == [2048]
        for key in EVAL_METRICS:
            assert data[key].shape == (1, 1)
        assert 0.0 <= data["em_mean_abs"][0, 0] < 60.0
    assert export_main([str(smoke_run.out), "--best", "--out", str(tmp_path / "b")]) == 0
    config = yaml.safe_load(model_files(tmp_path / "b")[2].read_text())
    assert config["num_timesteps"] == 2048
    assert config["selected_by"]["steps"] == 2048
    assert config["selected_by"]["n_users"] == 1
    assert isinstance(PPOPolicy.load(tmp_path / "b.zip"), PPOPolicy)


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_one_report_per_evaluation_on_the_projects_channel(smoke_run: SmokeRun) -> None:
    """stdout holds the model's path only; each evaluation is one [eval @ N steps] line on
    stderr (SB3's own evaluation lines, on stdout at any verbosity, are not printed)."""
    assert smoke_run.first.stdout.splitlines() == [str(smoke_run.out / "ppo_langctrl.zip")]
    lines = smoke_run.first.stderr.splitlines()
    assert [line.split("]")[0] for line in lines if "[eval @" in line] == ["[eval @ 2048 steps"]
    assert not any("rounded up" in line for line in lines)  # 2048: one whole rollout


def test_export_best_s_help_says_both_of_its_rules(monkeypatch: pytest.MonkeyPatch) -> None:
    """--best takes the most content for a phrase chooser and the lowest |AM| + |EM| otherwise:
    the help says what the code does."""
    from train.export import CONTENT_RULE, build_parser

    monkeypatch.setenv("COLUMNS", "1000")  # no wrapping inside a hyphenated word
    text = " ".join(build_parser().format_help().split())
    assert " ".join(CONTENT_RULE.split()) in text
    assert "lowest mean |AM| + mean |EM|" in text and "best_return/" in text


def test_one_name_per_best_in_the_docs() -> None:
    """ "best" is the model export --best chooses (runs/speech/best.zip); the training run's
    SB3 model of the highest return is best_return/: no page or example names a best/ model."""
    import re

    pages = [REPO / "README.md", *(REPO / "docs").glob("*.md")]
    pages += [*(REPO / "eval").glob("*.py"), *(REPO / "train").glob("*.py")]
    found = [
        f"{p.name}: {m.group(0)}"
        for p in pages
        for m in re.finditer(r"[\w/]*\bbest/[\w.]+", p.read_text(encoding="utf-8"))
    ]
    assert found == []


@pytest.mark.parametrize(("asked", "total"), [(32, 1024), (1024, 1024), (1025, 2048)])
def test_the_budget_is_rounded_up_to_whole_rollouts_and_said(asked: int, total: int) -> None:
    """PPO trains whole rollouts (n_steps x n_envs): a budget of 32 trains 1,024 steps, so the
    run's budget (its progress bar, its config, resume) is 1,024, and a line says why."""
    from train.config import resolve

    config = REPO / "configs" / "ppo_speech.yaml"
    run = resolve(TrainArgs(config=config, total_timesteps=asked, n_envs=2))
    assert run.total == total and run.asked == asked
    note = run.budget_note()
    if asked == total:
        assert note is None
    else:
        assert note is not None and f"{asked:,} steps is rounded up to {total:,}" in note
        assert "512 steps x 2 envs (1,024 steps)" in note


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_resume_extends_the_budget(smoke_run: SmokeRun) -> None:
    assert "resuming from" in smoke_run.resumed.stderr
    cfg = yaml.safe_load(model_files(smoke_run.out / "ppo_langctrl.zip")[2].read_text())
    assert cfg["num_timesteps"] == 4096


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_trained_model_drives_the_env(smoke_run: SmokeRun) -> None:
    policy = PPOPolicy.load(smoke_run.out / "ppo_langctrl.zip")
    env = _policy_env(policy)
    obs, _ = env.reset(seed=0)
    policy.reset()
    for _ in range(50):
        action = policy.act(obs)
        assert env.action_space.contains(action)
        obs, *_ = env.step(action)
    assert np.isfinite(obs).all()


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_export_copies_the_checkpoint(smoke_run: SmokeRun, tmp_path: Path) -> None:
    """A checkpoint exported as a model: the checkpoint's weights and normalisation, loadable."""
    from train.export import main as export_main

    assert export_main([str(smoke_run.out), "--steps", "2048", "--out", str(tmp_path / "x")]) == 0
    x_zip, x_norm, x_cfg = model_files(tmp_path / "x.zip")
    ckpt = smoke_run.checkpoints
    assert x_zip.read_bytes() == (ckpt / "ppo_langctrl_2048_steps.zip").read_bytes()
    assert x_norm.read_bytes() == (ckpt / "ppo_langctrl_vecnormalize_2048_steps.pkl").read_bytes()
    x_config = yaml.safe_load(x_cfg.read_text())
    assert x_config["num_timesteps"] == 2048
    assert x_config["exported_from"] == "checkpoints/ppo_langctrl_2048_steps.zip"
    exported = PPOPolicy.load(x_zip)
    env = _policy_env(exported)
    obs, _ = env.reset(seed=1)
    exported.reset()
    assert env.action_space.contains(exported.act(obs))


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_choice_only_export_keeps_the_base_paces(smoke_run: SmokeRun, tmp_path: Path) -> None:
    """--choice-only: the same network, only its phrase-choice correction kept."""
    from train.export import main as export_main

    stem = tmp_path / "c"
    argv = [str(smoke_run.out), "--steps", "2048", "--choice-only", "--out", str(stem)]
    assert export_main(argv) == 0
    config = yaml.safe_load(model_files(stem)[2].read_text())
    assert config["choice_only"] is True
    assert (config["residual"]["pace_scale"], config["residual"]["audio_scale"]) == (0.0, 0.0)
    assert config["residual"]["choice_scale"] > 0.0
    choice = PPOPolicy.load(model_files(stem)[0])
    spec = choice.residual.spec
    base = LanguageController(action_dim=3, terminal=spec.terminal, k_em=spec.k_em)
    env = _policy_env(choice)
    obs, _ = env.reset(seed=2)
    choice.reset()
    base.reset()
    for _ in range(30):
        act, want = choice.act(obs), base.act(obs)
        np.testing.assert_allclose(act[:2], want[:2], atol=1e-6)
        obs, *_ = env.step(act)


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_terminal_export_gives_the_base_a_terminal_phase(
    smoke_run: SmokeRun, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--terminal S: the exported model's base has a terminal phase of S s, recorded."""
    from train.export import main as export_main

    stem = tmp_path / "t"
    argv = [str(smoke_run.out), "--steps", "2048", "--terminal", "1", "--out", str(stem)]
    assert export_main(argv) == 0
    config = yaml.safe_load(model_files(stem)[2].read_text())
    assert config["residual"]["terminal"] == config["terminal_at_export"] == 1.0
    assert PPOPolicy.load(model_files(stem)[0]).residual.lc.terminal == 1.0
    bad = [str(smoke_run.out), "--steps", "2048", "--terminal", "-1", "--out", str(tmp_path / "b")]
    assert export_main(bad) != 0
    assert "--terminal" in capsys.readouterr().err
    assert not model_files(tmp_path / "b")[0].exists()


@pytest.mark.slow
@pytest.mark.xdist_group("ppo_smoke_run")
def test_finetune_stage_starts_from_the_checkpoint(smoke_run: SmokeRun, tmp_path: Path) -> None:
    """A fine-tune config (inherit, pace corrections off), started from a checkpoint."""
    tuned = tmp_path / "tuned"
    ckpt_zip = smoke_run.checkpoints / "ppo_langctrl_2048_steps.zip"
    fine = _train(
        *("--config", str(_finetune_config(tmp_path)), "--out", str(tuned)),
        *("--init-from", str(ckpt_zip), "--n-envs", "2", "--total-timesteps", "2048"),
        *("--n-eval-episodes", "0"),
    )
    assert fine.returncode == 0, fine.stderr[-3000:]
    assert "starting from the weights of" in fine.stderr
    t_cfg = yaml.safe_load(model_files(tuned / "ppo_finetune.zip")[2].read_text())
    assert t_cfg["train"]["init_from"] == ckpt_zip.name  # outside the working directory
    assert t_cfg["init_from_sha256"] == file_sha256(ckpt_zip)
    assert t_cfg["residual"]["pace_scale"] == 0.0
    assert isinstance(PPOPolicy.load(tuned / "ppo_finetune.zip"), PPOPolicy)


def test_export_names_the_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from train.export import main as export_main

    (tmp_path / "checkpoints").mkdir()
    assert export_main([str(tmp_path), "--steps", "5", "--out", str(tmp_path / "x")]) == 2
    assert "run_config.yaml" in capsys.readouterr().err
    (tmp_path / "run_config.yaml").write_text("train: {seed: 1}\n")
    assert export_main([str(tmp_path), "--steps", "5", "--out", str(tmp_path / "x")]) == 2
    assert "no train.name" in capsys.readouterr().err
    (tmp_path / "run_config.yaml").write_text("train: {name: my_run}\n")
    assert export_main([str(tmp_path), "--steps", "5", "--out", str(tmp_path / "x")]) == 2
    assert "my_run_5_steps.zip" in capsys.readouterr().err
    assert (
        export_main([str(tmp_path), "--steps", "5", "--out", str(tmp_path / "x"), "--name", "b"])
        == 2
    )
    assert "b_5_steps.zip" in capsys.readouterr().err
    assert not (tmp_path / "x.zip").exists()


def test_resume_without_checkpoint_fails_cleanly(tmp_path: Path) -> None:
    res = _train("--out", str(tmp_path), "--resume", "--total-timesteps", "100")
    assert res.returncode == 2
    assert "no checkpoint" in res.stderr


def test_load_config_reads_zoo_keys_and_train_section() -> None:
    hyper, section = load_config(CONFIG, "LangCtrl-v0")
    for key in ("n_envs", "n_timesteps", "policy", "normalize", "env_wrapper", "policy_kwargs"):
        assert key in hyper
    assert section["seed"] >= 1_000_000
    assert section["eval_seed"] + section["n_eval_episodes"] <= section["seed"]
    kw = _policy_kwargs(hyper["policy_kwargs"], CONFIG)
    assert kw["log_std_init"] < 0


def test_load_config_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"missing\.yaml"):
        load_config(tmp_path / "missing.yaml", "LangCtrl-v0")
    bad = tmp_path / "bad.yaml"
    bad.write_text("Other-v0: {n_envs: 1}\n")
    with pytest.raises(ConfigError, match="LangCtrl-v0"):
        load_config(bad, "LangCtrl-v0")
    bad.write_text("LangCtrl-v0: {frame_stack: 4}\n")
    with pytest.raises(ConfigError, match="frame_stack"):
        load_config(bad, "LangCtrl-v0")
    bad.write_text("LangCtrl-v0: {n_envs: 1}\ntrain: {bogus: 1}\n")
    with pytest.raises(ConfigError, match="bogus"):
        load_config(bad, "LangCtrl-v0")
    with pytest.raises(ConfigError, match="policy_kwargs"):
        _policy_kwargs("__import__('os')", bad)


def test_config_inherits_and_overrides_key_by_key(tmp_path: Path) -> None:
    base = tmp_path / "base.yaml"
    base.write_text(
        "LangCtrl-v0:\n  n_envs: 2\n  env_kwargs: {decision_hz: 25, w_am: 2.0}\n"
        "  env_wrapper: [a.B, c.D]\ntrain: {seed: 1000000, name: base}\n"
    )
    (tmp_path / "sub").mkdir()
    child = tmp_path / "sub" / "child.yaml"
    child.write_text(
        "inherit: ../base.yaml\nLangCtrl-v0:\n  env_kwargs: {w_am: 1.0}\n"
        "  env_wrapper: [e.F]\ntrain: {name: child}\n"
    )
    hyper, section = load_config(child, "LangCtrl-v0")
    assert hyper == {
        "n_envs": 2,
        "env_kwargs": {"decision_hz": 25, "w_am": 1.0},  # mappings merge
        "env_wrapper": ["e.F"],  # lists are replaced whole
    }
    assert section == {"seed": 1000000, "name": "child"}
    base.write_text("inherit: sub/child.yaml\nLangCtrl-v0: {n_envs: 1}\n")
    with pytest.raises(ConfigError, match="cycle"):
        load_config(child, "LangCtrl-v0")
    child.write_text("inherit: ../nowhere.yaml\nLangCtrl-v0: {n_envs: 1}\n")
    with pytest.raises(FileNotFoundError, match=r"nowhere\.yaml"):
        load_config(child, "LangCtrl-v0")
    child.write_text("inherit: [1]\nLangCtrl-v0: {n_envs: 1}\n")
    with pytest.raises(ConfigError, match="inherit"):
        load_config(child, "LangCtrl-v0")


def test_recorded_paths_describe_no_machine(tmp_path: Path) -> None:
    from train.provenance import recorded_args, recorded_path

    assert recorded_path("runs/ppo") == "runs/ppo"
    assert recorded_path(Path.cwd() / "runs" / "ppo") == "runs/ppo"
    assert recorded_path(tmp_path / "elsewhere" / "run") == "run"
    args = recorded_args(TrainArgs(out=tmp_path / "x", init_from=tmp_path / "m.zip"))
    assert (args["out"], args["init_from"], args["config"]) == ("x", "m.zip", "configs/ppo.yaml")
    assert recorded_args({"out": str(tmp_path / "y"), "seed": 1}) == {"out": "y", "seed": 1}


def test_schedules_and_cli_overrides() -> None:
    lin = _schedule("lin_3e-4")
    assert lin(1.0) == pytest.approx(3e-4) and lin(0.5) == pytest.approx(1.5e-4)
    assert _schedule(0.2) == 0.2
    args, given = parse_args(["--total-timesteps", "5000", "--seed", "1000001", "--resume"])
    assert args.total_timesteps == 5000 and args.seed == 1_000_001 and args.resume
    assert given == {"total_timesteps", "seed", "resume"}
    with pytest.raises(ConfigError, match="vec_env"):
        TrainArgs(vec_env="threads")


def test_auto_vec_env_uses_subprocesses_only_with_a_core_to_spare(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import train.factories

    assert TrainArgs().vec_env == "auto"
    for cores, expected in ((2, False), (3, True), (16, True)):
        monkeypatch.setattr(train.factories, "usable_cores", lambda cores=cores: cores)
        assert use_subprocesses("auto", 2) is expected
        assert use_subprocesses("subproc", 2) and not use_subprocesses("dummy", 2)
        assert not use_subprocesses("auto", 1) and not use_subprocesses("subproc", 1)


def test_periodic_evaluation_meets_exactly_the_held_out_seeds() -> None:
    """The evaluation env's resets go eval_seed, eval_seed + 1, ... from the very first one (SB3's
    make_vec_env would seed the first reset at random, a different user in every run)."""
    import gymnasium as gym

    from train.config import resolve
    from train.factories import make_envs

    args, given = parse_args(["--config", str(CONFIG), "--n-eval-episodes", "3", "--n-envs", "1"])
    run = resolve(args, given)
    env, eval_env = make_envs(run)
    try:
        assert run.wrapper is not None
        got = []
        for _ in range(4):
            eval_env.reset()
            got.append(eval_env.envs[0].unwrapped.np_random.bit_generator.state)
        for i, k in enumerate([0, 1, 2, 0]):
            plain = run.wrapper(gym.make(args.env_id, **run.env_kwargs))
            plain.reset(seed=args.eval_seed + k)
            assert got[i] == plain.unwrapped.np_random.bit_generator.state, f"reset {i}"
    finally:
        env.close()
        eval_env.close()


def _fresh_model(seed: int, config: Path = CONFIG, normalize: bool = True) -> tuple[Any, Any]:
    """An untrained PPO on the config's env (one in-process env), and its VecEnv."""
    from stable_baselines3 import PPO

    from train.config import ppo_kwargs, resolve
    from train.factories import make_envs

    run = resolve(TrainArgs(config=config, n_envs=1, vec_env="dummy", n_eval_episodes=0))
    if not normalize:
        run.normalize = None
    env, _ = make_envs(run)
    return PPO("MlpPolicy", env, seed=seed, device="cpu", **ppo_kwargs(run)), env


def test_init_from_copies_weights_and_normalisation(tmp_path: Path) -> None:
    """--init-from: the new run starts with the source's network and statistics, nothing else."""
    from train.resume import init_from_model

    src, src_env = _fresh_model(1)
    src_env.obs_rms.mean = np.random.default_rng(0).normal(size=src_env.obs_rms.mean.shape)
    src_env.ret_rms.var = np.array(7.0)
    src.save(tmp_path / "src.zip")
    src_env.save(str(tmp_path / "src_vecnormalize.pkl"))
    # the fine-tune config (pace corrections off) has the same spaces, so the network fits
    dst, dst_env = _fresh_model(2, _finetune_config(tmp_path))
    before = {k: v.clone() for k, v in dst.policy.state_dict().items()}
    digest = init_from_model(dst, dst_env, tmp_path / "src")
    for key, value in src.policy.state_dict().items():
        assert np.array_equal(dst.policy.state_dict()[key].numpy(), value.numpy()), key
    assert any(
        not np.array_equal(before[k].numpy(), v.numpy()) for k, v in src.policy.state_dict().items()
    )
    np.testing.assert_array_equal(dst_env.obs_rms.mean, src_env.obs_rms.mean)
    assert float(dst_env.ret_rms.var) == 7.0
    assert dst_env.training  # statistics go on adapting during the fine-tune
    assert dst.learning_rate == pytest.approx(1e-4)  # the new config's hyperparameters
    assert len(digest) == 64

    # a checkpoint's pickle is found by its own name
    src.save(tmp_path / "run_2048_steps.zip")
    src_env.save(str(tmp_path / "run_vecnormalize_2048_steps.pkl"))
    dst2, dst2_env = _fresh_model(3)
    init_from_model(dst2, dst2_env, tmp_path / "run_2048_steps.zip")
    np.testing.assert_array_equal(dst2_env.obs_rms.mean, src_env.obs_rms.mean)


def test_init_from_rejects_what_does_not_fit(tmp_path: Path) -> None:
    from train.resume import init_files, init_from_model

    with pytest.raises(FileNotFoundError, match=r"nope\.zip"):
        init_files(tmp_path / "nope")
    src, _ = _fresh_model(1)
    src.save(tmp_path / "src.zip")
    dst, dst_env = _fresh_model(2)
    with pytest.raises(FileNotFoundError, match=r"src_vecnormalize\.pkl"):
        init_from_model(dst, dst_env, tmp_path / "src.zip")  # weights without their statistics
    plain, plain_env = _fresh_model(2, normalize=False)
    src_env_path = tmp_path / "src_vecnormalize.pkl"
    _fresh_model(1)[1].save(str(src_env_path))
    with pytest.raises(ConfigError, match="has none"):
        init_from_model(plain, plain_env, tmp_path / "src.zip")
    # unreadable files
    (tmp_path / "bad.zip").write_bytes(b"not a zip")
    with pytest.raises(ConfigError, match=r"bad\.zip"):
        init_from_model(dst, dst_env, tmp_path / "bad.zip")
    src_env_path.write_bytes(b"garbage")
    with pytest.raises(ConfigError, match=r"src_vecnormalize\.pkl"):
        init_from_model(dst, dst_env, tmp_path / "src.zip")
    import pickle

    src_env_path.write_bytes(pickle.dumps({"obs_rms": 1}))
    with pytest.raises(ConfigError, match="not a VecNormalize"):
        init_from_model(dst, dst_env, tmp_path / "src.zip")
    _fresh_model(1)[1].save(str(src_env_path))
    # another network shape (config with pi=[32])
    cfg = yaml.safe_load(CONFIG.read_text())
    cfg["LangCtrl-v0"]["policy_kwargs"] = "dict(net_arch=dict(pi=[32], vf=[32]))"
    small_cfg = tmp_path / "small.yaml"
    small_cfg.write_text(yaml.safe_dump(cfg))
    small, small_env = _fresh_model(2, small_cfg)
    with pytest.raises(ConfigError, match="does not fit"):
        init_from_model(small, small_env, tmp_path / "src.zip")
    # another observation space (scores choice mode: more children scores in the action)
    cfg = yaml.safe_load(CONFIG.read_text())
    cfg["LangCtrl-v0"]["env_kwargs"]["choice_mode"] = "scores"
    cfg["LangCtrl-v0"]["env_wrapper"][1]["train.wrappers.ResidualLCWrapper"]["choice_mode"] = (
        "scores"
    )
    scores_cfg = tmp_path / "scores.yaml"
    scores_cfg.write_text(yaml.safe_dump(cfg))
    other, other_env = _fresh_model(2, scores_cfg)
    with pytest.raises(ConfigError, match="space has shape"):
        init_from_model(other, other_env, tmp_path / "src.zip")


@pytest.mark.parametrize(
    "config",
    sorted([*(REPO / "configs").glob("ppo*.yaml"), *(REPO / "configs/experiments").glob("*.yaml")]),
    ids=lambda p: p.name,
)
def test_every_shipped_config_resolves(config: Path) -> None:
    """Each training config parses: its train section, wrappers, schedules and network."""
    from train.config import ppo_kwargs, resolve

    run = resolve(TrainArgs(config=config))
    kwargs = ppo_kwargs(run)
    assert isinstance(kwargs["policy_kwargs"], dict)
    assert run.args.seed >= 1_000_000 and run.wrapper is not None


def _weights(path: Path) -> dict[str, np.ndarray]:
    from stable_baselines3 import PPO

    model = PPO.load(path, device="cpu")
    return {k: v.numpy().copy() for k, v in model.policy.state_dict().items()}


def _same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> bool:
    return all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.slow
def test_resume_loses_nothing(tmp_path: Path) -> None:
    """Interrupted after its first update and resumed: the next update is learned on top of it,
    the evaluation history and the best model carry over, and the budget and settings are the
    interrupted run's."""
    out = tmp_path / "run"
    ckpt = out / "checkpoints"
    first = _train(
        *("--out", str(out), "--n-envs", "2", "--eval-freq", "2048", "--checkpoint-freq", "2048"),
        *("--total-timesteps", "2048", "--n-eval-episodes", "1", "--seed", "1000123"),
    )
    assert first.returncode == 0, first.stderr[-3000:]
    for f in model_files(out / "ppo_langctrl.zip"):  # as if killed before the end
        f.unlink()
    point = tmp_path / "point.zip"
    shutil.copyfile(ckpt / "resume" / "ppo_langctrl.zip", point)

    again = _train("--out", str(out), "--resume", "--total-timesteps", "4096")
    assert again.returncode == 0, again.stderr[-3000:]
    assert "the state after the update at 2048 steps" in again.stderr
    snap2 = _weights(ckpt / "ppo_langctrl_2048_steps.zip")  # taken before that update
    snap4 = _weights(ckpt / "ppo_langctrl_4096_steps.zip")
    assert not _same(snap4, snap2)  # the first batch was learned from ...
    assert _same(snap4, _weights(point))  # ... and kept
    assert not _same(_weights(out / "ppo_langctrl.zip"), snap4)  # the next update happened
    run_cfg = yaml.safe_load((out / "run_config.yaml").read_text())
    assert run_cfg["train"]["seed"] == 1000123 and run_cfg["train"]["n_eval_episodes"] == 1
    with np.load(out / "eval" / "evaluations.npz") as ev:
        assert ev["timesteps"].tolist() == [2048, 4096]
        means = ev["results"].mean(axis=1)
    best = yaml.safe_load((out / "best_return" / "ppo_langctrl_config.yaml").read_text())
    assert best["num_timesteps"] == [2048, 4096][int(np.argmax(means))]
    assert best["eval_mean_reward"] == pytest.approx(float(means.max()))

    # --resume alone keeps the run's budget (4096 steps), not the config's (3e5)
    final = (out / "ppo_langctrl.zip").read_bytes()
    done = _train("--out", str(out), "--resume")
    assert done.returncode == 0, done.stderr[-3000:]
    assert "nothing to do" in done.stderr
    assert (out / "ppo_langctrl.zip").read_bytes() == final
    # another setting is refused, naming it
    other = _train("--out", str(out), "--resume", "--seed", "1000999")
    assert other.returncode == 2 and "--seed 1000999" in other.stderr


@pytest.mark.slow
def test_ctrl_c_exits_130_with_one_line(tmp_path: Path) -> None:
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) in a run with worker
    processes: exit status 130, one line on stderr, and the resume point on disk."""
    import signal
    import time

    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    cmd = [sys.executable, "-m", "train.ppo", "--config", str(TWO_ENVS), "--no-progress-bar"]
    cmd += ["--n-envs", "2", "--vec-env", "subproc", "--n-eval-episodes", "0"]
    # A short run first, so that the workers load the env's compiled kernels from numba's cache
    # instead of compiling them (minutes of CPU under load on a fresh clone) when Ctrl-C comes
    warm = subprocess.run(
        [*cmd, "--out", str(tmp_path / "warm"), "--total-timesteps", "64"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert warm.returncode == 0, warm.stderr[-3000:]
    cmd += ["--out", str(out)]
    proc = subprocess.Popen(
        [*cmd, "--total-timesteps", "2048000"],  # whole rollouts: no line about rounding
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        # SIGINT handled by default in the run whatever the test process's disposition is
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    point = out / "checkpoints" / "resume" / "ppo_langctrl.zip"
    t0 = time.monotonic()
    while not point.is_file() and time.monotonic() - t0 < 120 and proc.poll() is None:
        time.sleep(0.2)
    time.sleep(2.0)  # well inside the first rollout
    # Under a loaded machine a first Ctrl-C was seen to be lost (the run went on training; cause
    # not found, see HISTORY.md): press it again, as a person would, at most five times
    stderr = ""
    for _ in range(5):
        os.killpg(proc.pid, signal.SIGINT)
        try:
            _stdout, stderr = proc.communicate(timeout=60)
            break
        except subprocess.TimeoutExpired:
            continue
    else:
        proc.kill()
        pytest.fail("train.ppo did not end after five Ctrl-C")
    assert proc.returncode == 130, stderr[-3000:]
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("langctrl train: interrupted at"), stderr[-3000:]
    assert "continue with --resume" in lines[0]
    assert point.is_file()


def test_resume_point_swap_and_sources(tmp_path: Path) -> None:
    """The resume point is replaced whole; a crash between the renames leaves the old one."""
    from train.resume import resume_files, resume_source, save_resume_point

    ckpt = tmp_path / "checkpoints"
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        resume_source(ckpt, "m")
    model, _env = _fresh_model(1)
    save_resume_point(model, ckpt, "m")
    zip_path, pkl = resume_files(ckpt, "m")
    assert zip_path.is_file() and pkl.is_file()
    assert resume_source(ckpt, "m") == (zip_path, pkl, True)
    save_resume_point(model, ckpt, "m")  # again: replaced, nothing left over
    assert sorted(p.name for p in ckpt.iterdir()) == ["resume"]
    (ckpt / "resume").rename(ckpt / ".resume.old")  # killed between the two renames
    assert resume_source(ckpt, "m")[0] == ckpt / ".resume.old" / "m.zip"
    shutil.rmtree(ckpt / ".resume.old")
    model.save(checkpoint_files(ckpt, "m", 4096)[0])
    _env.save(str(checkpoint_files(ckpt, "m", 4096)[1]))
    assert resume_source(ckpt, "m") == (*checkpoint_files(ckpt, "m", 4096), False)


def test_restore_history_keeps_what_the_resume_point_saw(tmp_path: Path) -> None:
    from stable_baselines3.common.callbacks import EvalCallback

    from train.callbacks import restore_history

    (tmp_path / "eval").mkdir()
    np.savez(
        tmp_path / "eval" / "evaluations.npz",
        timesteps=[2048, 4096, 6144],
        results=[[-1.0, -2.0], [-0.5, -0.7], [-0.1, -0.2]],
        ep_lengths=[[10, 10], [10, 10], [10, 10]],
    )
    _model, env = _fresh_model(1)
    cb = EvalCallback(env, n_eval_episodes=2)
    best_cfg = tmp_path / "best.yaml"
    assert restore_history(cb, tmp_path / "eval", best_cfg, 4096) == 2
    assert cb.evaluations_timesteps == [2048, 4096]
    assert cb.best_mean_reward == pytest.approx(-0.6)
    best_cfg.write_text(yaml.safe_dump({"eval_mean_reward": -0.15}))  # best/ came from 6144
    restore_history(cb, tmp_path / "eval", best_cfg, 4096)
    assert cb.best_mean_reward == pytest.approx(-0.15)


def test_restore_history_keeps_the_recorded_metrics(tmp_path: Path) -> None:
    from train.callbacks import EVAL_METRICS, MetricsEvalCallback, restore_history

    run = _scored_run(tmp_path, [[0.1, 0.2], [0.3, 0.4]], [[0.5, 0.6], [0.7, 0.8]])
    _model, env = _fresh_model(1)
    cb = MetricsEvalCallback(env, n_eval_episodes=2)
    assert restore_history(cb, run / "eval", tmp_path / "none.yaml", 10) == 1
    assert cb.evaluations_metrics["abs_am"] == [[0.1, 0.2]]
    assert cb.evaluations_metrics["em_mean_abs"] == [[0.5, 0.6]]
    assert set(cb.evaluations_metrics) == set(EVAL_METRICS)


def test_resume_of_a_run_recorded_before_the_metrics_keeps_saving(tmp_path: Path) -> None:
    """An evaluations.npz without the metrics (an older run): the restored rows are NaN per user,
    so the next evaluation's rows stack with them and the file is written again."""
    from train.callbacks import MetricsEvalCallback, restore_history

    (tmp_path / "eval").mkdir()
    np.savez(
        tmp_path / "eval" / "evaluations.npz",
        timesteps=[10, 20],
        results=[[-1.0, -2.0], [-0.5, -0.7]],
        ep_lengths=[[10, 10], [10, 10]],
    )
    _model, env = _fresh_model(1)
    cb = MetricsEvalCallback(env, n_eval_episodes=2, log_path=str(tmp_path / "eval"))
    assert restore_history(cb, tmp_path / "eval", tmp_path / "none.yaml", 20) == 2
    cb.evaluations_timesteps.append(30)
    cb.evaluations_results.append([-0.1, -0.2])
    cb.evaluations_length.append([10, 10])
    for key, row in (("abs_am", [0.1, 0.2]), ("em_mean_abs", [0.3, 0.4]), ("a_dev", [0.2, 0.2])):
        cb.evaluations_metrics[key].append(row)
    cb._save_metrics()
    with np.load(tmp_path / "eval" / "evaluations.npz") as data:
        assert data["abs_am"].shape == (3, 2)
        assert np.isnan(data["abs_am"][:2]).all() and data["abs_am"][2].tolist() == [0.1, 0.2]


def test_fresh_run_refuses_a_non_empty_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from train.ppo import main as train_main

    (tmp_path / "notes.txt").write_text("keep")
    assert train_main(["--config", str(CONFIG), "--out", str(tmp_path)]) == 2
    assert "already holds files" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]


def _scored_run(tmp_path: Path, am: list[list[float]], em: list[list[float]]) -> Path:
    """A run directory with recorded evaluations at 10, 20, ... steps and their checkpoints."""
    (tmp_path / "eval").mkdir()
    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "run_config.yaml").write_text("train: {name: m, eval_seed: 900000}\n")
    steps = [10 * (i + 1) for i in range(len(am))]
    np.savez(
        tmp_path / "eval" / "evaluations.npz",
        timesteps=steps,
        results=np.zeros((len(am), 2)),
        ep_lengths=np.ones((len(am), 2)),
        abs_am=am,
        em_mean_abs=em,
        a_dev=np.full((len(am), 2), 0.2),
    )
    for n in steps:
        for f in checkpoint_files(tmp_path / "checkpoints", "m", n):
            f.write_bytes(b"checkpoint")
    return tmp_path


def test_best_steps_takes_the_lowest_score_earliest_on_a_tie(tmp_path: Path) -> None:
    from train.export import best_steps, eval_scores

    am = [[0.4, 0.2], [0.1, 0.1], [0.0, 0.2], [math.nan, 0.0]]
    em = [[0.3, 0.3], [0.3, 0.3], [0.3, 0.3], [0.0, 0.0]]
    run = _scored_run(tmp_path, am, em)
    scores = eval_scores(run)
    assert [e.steps for e in scores] == [10, 20, 30]  # 40: a session did not end (NaN)
    assert scores[0].score == pytest.approx(0.6)
    chosen = best_steps(run, "m")
    assert (chosen.steps, chosen.score) == (20, pytest.approx(0.4))  # 30 ties, 20 is earlier
    checkpoint_files(run / "checkpoints", "m", 20)[0].unlink()
    assert best_steps(run, "m").steps == 30  # only steps with a checkpoint are eligible


def test_best_of_a_phrase_choosers_run_is_chosen_by_content(tmp_path: Path) -> None:
    from train.export import CONTENT_RULE, best_steps, eval_scores

    am = [[0.1, 0.2], [0.1, 1.5], [0.1, 0.1], [0.2, 0.1]]
    run = _scored_run(tmp_path, am, [[0.0, 0.0]] * 4)
    with np.load(run / "eval" / "evaluations.npz") as data:
        arrays = dict(data)
    arrays["content_share"] = [[0.80, 0.82], [0.95, 0.95], [0.84, 0.84], [0.86, 0.86]]
    arrays["voice_natural"] = [[0.97, 0.97], [0.97, 0.97], [0.975, 0.975], [0.90, 0.90]]
    np.savez(run / "eval" / "evaluations.npz", **arrays)
    scores = eval_scores(run)
    assert all(e.speech for e in scores) and scores[1].within == 0.5
    chosen = best_steps(run, "m")
    # 20: a session beyond 1 s; 40: its voice 0.08 below the best; of the rest 30 says most
    assert chosen.steps == 30 and chosen.content_share == pytest.approx(0.84)
    assert chosen.record({"train": {"eval_seed": 900000}})["rule"] == CONTENT_RULE
    # with the base's own figures (train.ppo evaluates it before training): against those
    base = {k: np.asarray(arrays[k][0], float) for k in ("abs_am", "em_mean_abs", "a_dev")}
    base.update(content_share=np.full(2, 0.83), voice_natural=np.full(2, 0.915))
    np.savez(run / "eval" / "base.npz", **base)
    assert best_steps(run, "m").steps == 40  # its voice 0.90 is within 0.02 of the base's
    # legs in step (issue 44): 40 drops a boundary the base keeps; NaN (no boundary) counts out
    arrays["legs_in_step"] = [[1.0, 1.0], [1.0, 1.0], [1.0, math.nan], [1.0, 0.5]]
    np.savez(run / "eval" / "evaluations.npz", **arrays)
    assert eval_scores(run)[2].legs_in_step == 1.0
    base["legs_in_step"] = np.array([1.0, 1.0])
    np.savez(run / "eval" / "base.npz", **base)
    chosen = best_steps(run, "m")
    assert chosen.steps == 30 and chosen.record({})["legs_in_step"] == 1.0
    base["voice_natural"] = np.full(2, 1.0)
    np.savez(run / "eval" / "base.npz", **base)
    with pytest.raises(ValueError, match="no checkpoint holds"):
        best_steps(run, "m")


def test_best_names_what_is_missing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from train.export import main as export_main

    (tmp_path / "run_config.yaml").write_text("train: {name: m}\n")
    assert export_main([str(tmp_path), "--best", "--out", str(tmp_path / "x")]) == 2
    assert "evaluations.npz" in capsys.readouterr().err
    (tmp_path / "eval").mkdir()
    np.savez(tmp_path / "eval" / "evaluations.npz", timesteps=[5], results=[[0.0]])
    assert export_main([str(tmp_path), "--best", "--out", str(tmp_path / "x")]) == 2
    assert "no abs_am" in capsys.readouterr().err
    (tmp_path / "r").mkdir()
    run = _scored_run(tmp_path / "r", [[0.1]], [[0.2]])
    for f in checkpoint_files(run / "checkpoints", "m", 10):
        f.unlink()
    assert export_main([str(run), "--best", "--out", str(tmp_path / "x")]) == 2
    assert "multiple of checkpoint_freq" in capsys.readouterr().err
    assert not (tmp_path / "x.zip").exists()


def test_export_and_ensemble_never_replace_files_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from train.ensemble import main as ensemble_main
    from train.export import main as export_main

    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "run_config.yaml").write_text("train: {name: m}\n")
    for f in checkpoint_files(tmp_path / "checkpoints", "m", 5):
        f.write_bytes(b"checkpoint")
    (tmp_path / "x_config.yaml").write_text("mine")
    assert export_main([str(tmp_path), "--steps", "5", "--out", str(tmp_path / "x")]) == 2
    assert "x_config.yaml exists; give --overwrite" in capsys.readouterr().err
    assert (tmp_path / "x_config.yaml").read_text() == "mine"
    assert not (tmp_path / "x.zip").exists()
    manifest = tmp_path / "e.yaml"
    manifest.write_text("mine")
    assert ensemble_main([str(tmp_path / "a.zip"), "--out", str(manifest)]) == 2
    assert "e.yaml exists; give --overwrite" in capsys.readouterr().err
    assert manifest.read_text() == "mine"


def test_subprocess_and_in_process_envs_give_the_same_rollout() -> None:
    """--vec-env subproc and dummy hand PPO the same float32 observations and rewards."""
    from train.config import resolve
    from train.factories import make_envs

    got = {}
    for vec_env in ("dummy", "subproc"):
        run = resolve(TrainArgs(config=CONFIG, vec_env=vec_env, n_eval_episodes=0, n_envs=2))
        env, _ = make_envs(run)
        venv, rng = env.venv, np.random.default_rng(0)
        steps = [(venv.reset(), np.zeros(2, np.float32))]
        for _ in range(40):
            obs, rew, _, _ = venv.step(rng.uniform(-1, 1, (2, 3)).astype(np.float32))
            steps.append((obs.copy(), rew.copy()))
        venv.close()
        got[vec_env] = steps
    for (o1, r1), (o2, r2) in zip(got["dummy"], got["subproc"], strict=True):
        assert o1.dtype == o2.dtype == np.float32 and r1.dtype == r2.dtype == np.float32
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2)
