"""The speech people hear (issue 38): the content rule ``lc-fill``, its phrase action, and the
learned phrase chooser's env (``train.choices.ChoicePoints``) against the evaluation's own runs."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from eval.compare import Job, run_episode
from langenv.errors import ConfigError
from langenv.task import observation as ob
from langenv.task.observation import Obs
from langenv.users import PerturbedUser
from langenv.worlds import WorldEnv, WorldSplit
from policies.analytic import (
    ANALYTIC,
    FILL_ANTICIPATE,
    FILL_K_C,
    FILL_MARGIN,
    FILL_PAUSE_SCALE,
    FILL_TERMINAL,
    LanguageController,
    fill_choice,
    make_analytic,
)
from policies.learned import ResidualSpec

ROOT = Path(__file__).resolve().parents[1]
SPLIT = ROOT / "configs" / "ppo_speech.yaml"


def _obs(t_x: float, children: list[tuple[float, float]], max_children: int = 4) -> np.ndarray:
    """An observation with ``t_x`` and valid children ``(t_min, t_max)``; the rest empty."""
    obs = np.zeros(ob.observation_size(max_children), np.float32)
    obs[Obs.T_X] = t_x / ob.T_SCALE
    obs[Obs.IN_PAUSE] = 1.0
    for k in range(max_children):
        i = ob.child_index(k)
        if k < len(children):
            obs[i : i + 3] = (1.0, children[k][0] / ob.T_SCALE, children[k][1] / ob.T_SCALE)
        else:
            obs[i] = -1.0
    return obs


def _target(obs: np.ndarray, u: float, children: list[tuple[float, float]]) -> int:
    """The child the env says for action ``u`` (its rule: the mid nearest ``t_x 2^{2u}``)."""
    target = ob.seconds(obs, Obs.T_X) * 2.0 ** (2.0 * u)
    mids = [0.5 * (lo + hi) for lo, hi in children]
    return int(np.argmin([abs(target - m) for m in mids]))


def test_fill_choice_says_the_longest_wording_that_still_fits() -> None:
    kids = [(4.0, 9.0), (6.0, 11.0), (8.0, 13.0), (3.0, 4.0)]
    obs = _obs(8.0, kids)
    # t_min <= 8 - 1: children 0, 1 and 3 fit; the longest is 1, which the paper's rule says
    # too (mids 6.5, 8.5, 10.5, 3.5: 8.5 is nearest t_x)
    u = fill_choice(obs, margin=1.0)
    assert _target(obs, u, kids) == 1 and u == 0.0  # the paper's own choice: no action
    u = fill_choice(obs, margin=0.0)  # child 2 fits now
    assert _target(obs, u, kids) == 2 and u > 0.0
    u = fill_choice(obs, margin=6.0)  # nothing fits: the shortest
    assert _target(obs, u, kids) == 3 and u < 0.0
    u = fill_choice(obs, margin=1.0, horizon=16.0)  # a slow person: plan with more time
    assert _target(obs, u, kids) == 2
    assert fill_choice(_obs(8.0, kids[:1]), margin=0.0) == 0.0  # one child: nothing to choose


def test_lc_fill_is_registered_with_its_tuned_settings() -> None:
    assert "lc-fill" in ANALYTIC and ANALYTIC["lc-fill"][0]
    policy = make_analytic("lc-fill")
    assert isinstance(policy, LanguageController)
    assert (policy.choice, policy.fill_margin) == ("fill", FILL_MARGIN)
    assert (policy.fill_anticipate, policy.pause_scale) == (FILL_ANTICIPATE, FILL_PAUSE_SCALE)
    assert policy.gains.k_c == FILL_K_C and policy.graph_role == "graph"
    assert policy.pace_law() is None  # its pauses and anticipation need Python steps
    text = (ROOT / "pyproject.toml").read_text()
    assert all(f'\n{name} = "policies:load_policy"' in text for name in ANALYTIC)
    with pytest.raises(KeyError, match="lc-fill"):
        make_analytic("lc-fil")
    for bad in ({"choice": "longest"}, {"pause_scale": 0.0}, {"fill_anticipate": -1.0}):
        with pytest.raises(ConfigError):
            LanguageController(**bad)  # type: ignore[arg-type]


def test_lc_fill_end_is_lc_fill_with_a_terminal_phase() -> None:
    fill, end = make_analytic("lc-fill"), make_analytic("lc-fill-end")
    assert isinstance(fill, LanguageController) and isinstance(end, LanguageController)
    assert (fill.terminal, end.terminal) == (0.0, FILL_TERMINAL) and FILL_TERMINAL > 0.0
    same = ("choice", "fill_margin", "fill_anticipate", "pause_scale", "gains", "k_em")
    assert all(getattr(fill, k) == getattr(end, k) for k in same)


def test_a_chooser_on_a_terminal_base_is_lc_fill_end_at_zero_correction() -> None:
    """A phrase chooser deployed on ``lc-fill-end``'s base (``terminal`` in its config): at
    ``r = 0`` its every action is ``lc-fill-end``'s, terminal phase included."""
    import gymnasium as gym

    import langenv
    from policies.learned import ResidualLC

    spec = ResidualSpec(decisions="choices", decision_hz=500, pace_scale=0.0, audio_scale=0.0,
                        choice_mode="target", k_c=FILL_K_C, choice="fill",
                        fill_margin=FILL_MARGIN, fill_anticipate=FILL_ANTICIPATE,
                        pause_scale=FILL_PAUSE_SCALE, terminal=FILL_TERMINAL)  # fmt: skip
    core, ref = ResidualLC(spec), make_analytic("lc-fill-end")
    env = gym.make(langenv.ENV_ID, decision_hz=500, choice_mode="target", max_episode_steps=30000)
    obs, _ = env.reset(seed=3)
    core.start(obs)
    ref.reset()
    phases, done = set(), False
    while not done:
        a_ref = ref.act(obs)
        phases.add(ref.phase(np.asarray(obs).tolist()))
        np.testing.assert_array_equal(core.action(np.zeros(3)), a_ref)
        obs, _, terminated, truncated, _ = env.step(a_ref)
        core.observe(obs)
        done = terminated or truncated
    assert terminated and "terminal" in phases


def test_choices_decisions_need_a_phrase_only_target_residual_at_500_hz() -> None:
    ok = dict(decisions="choices", decision_hz=500, pace_scale=0.0, audio_scale=0.0)
    ResidualSpec(**ok)  # type: ignore[arg-type]
    for bad in ({"decision_hz": 25}, {"pace_scale": 0.1}):
        with pytest.raises(ConfigError, match="choices"):
            ResidualSpec(**{**ok, **bad})  # type: ignore[arg-type]
    assert ResidualSpec(**ok, terminal=1.0).base().terminal == 1.0  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="decisions"):
        ResidualSpec(decisions="ticks")  # type: ignore[arg-type]


def _same(x: float, y: float) -> bool:
    """Equal to the last bit, NaN equal to NaN."""
    return (math.isnan(x) and math.isnan(y)) or x == pytest.approx(y, abs=1e-12)


def test_the_choice_env_at_zero_correction_is_lc_fill_tick_for_tick(tmp_path: Path) -> None:
    from train.choices import ChoicePoints

    split = WorldSplit.load(SPLIT)
    env = ChoicePoints(WorldEnv(split, "validation", {"decision_hz": 500}, 2), w_legs=3.0)
    for _ in range(2):
        obs, _ = env.reset()
        assert env.observation_space.contains(obs)
        seed = env.env.world["user_seed"]
        done, decisions = False, 0
        while not done:
            obs, reward, terminated, truncated, info = env.step(np.zeros(3, np.float32))
            decisions += 1
            done = terminated or truncated
        assert terminated and decisions >= 2
        job = Job("lc-fill", f"s{seed}", seed, None, str(tmp_path), False, False, None,
                  exercise="shoulder_extension", save_log=False,
                  user_model=PerturbedUser(split.perturbations))  # fmt: skip
        row = run_episode(job)
        for key in ("content_share", "voice_natural", "em_mean_abs", "legs_in_step", "sm_max_abs"):
            assert _same(info[key], row[key]), key
        assert info["am"] == pytest.approx(row["am"], abs=1e-12)
        assert math.isfinite(row["legs_in_step"])  # shoulder_extension's script marks its legs
        assert info["reward_legs"] == pytest.approx(3.0 * info["legs_in_step"])
        terms = [v for k, v in info.items() if k.startswith("reward_")]
        assert reward == pytest.approx(sum(terms)) and info["reward_content"] > 0.0
        assert math.isfinite(reward)
    with pytest.raises(ConfigError, match="after the episode ended"):
        env.step(np.zeros(3, np.float32))


def test_the_choice_env_needs_ticks() -> None:
    import gymnasium as gym

    import langenv
    from train.choices import ChoicePoints

    with pytest.raises(ConfigError, match="500 Hz"):
        ChoicePoints(gym.make(langenv.ENV_ID, decision_hz=25))
    with pytest.raises(ConfigError, match="w_content"):
        ChoicePoints(gym.make(langenv.ENV_ID, decision_hz=500), w_content=-1.0)
    with pytest.raises(ConfigError, match="am_scale must be finite and > 0"):
        ChoicePoints(gym.make(langenv.ENV_ID, decision_hz=500), am_scale=0.0)
    with pytest.raises(ConfigError, match=r"unknown argument\(s\) w_speed"):
        ChoicePoints(gym.make(langenv.ENV_ID, decision_hz=500), w_speed=1.0)


def test_the_choice_reward_pays_each_term_once() -> None:
    from train.shaping import ChoiceReward

    r = ChoiceReward(w_content=2.0, w_legs=1.0, w_length=0.5, w_am_far=3.0, w_stop=7.0)
    ended = r.terms((0.5, 0.8, float("nan")), em_mean=0.2, length=10.0, am=-1.5)
    assert ended["reward_content"] == 1.0 and ended["reward_voice"] == 4.0
    assert ended["reward_legs"] == 0.0 and ended["reward_length"] == -5.0
    assert ended["reward_em"] == pytest.approx(-0.2)
    assert ended["reward_am"] == pytest.approx(-1.5 - 0.5 * math.log1p(15.0))
    assert ended["reward_am_far"] == -3.0
    stopped = r.terms((0.5, 0.8, 1.0), em_mean=0.2, length=10.0, am=None)
    assert (stopped["reward_am"], stopped["reward_am_far"]) == (-7.0, 0.0)


@pytest.fixture(scope="module")
def tiny_chooser(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A learned phrase chooser of configs/ppo_speech.yaml, trained in-process for two short
    rollouts on two envs with a periodic evaluation on two validation people."""
    from train.config import TrainArgs
    from train.ppo import train

    root = tmp_path_factory.mktemp("tiny_chooser")
    config = root / "tiny.yaml"
    config.write_text(
        f"inherit: {SPLIT}\nLangCtrl-v0: {{n_steps: 16, batch_size: 16, n_epochs: 1}}\n"
    )
    args = TrainArgs(
        config=config,
        out=root / "run",
        total_timesteps=64,
        n_envs=2,
        vec_env="dummy",
        n_eval_episodes=2,
        eval_freq=32,
        checkpoint_freq=32,
        progress_bar=False,
        tensorboard=False,
    )
    given = {"out", "n_envs", "n_eval_episodes", "eval_freq", "checkpoint_freq", "total_timesteps"}
    return train(args, given=given)


def test_a_chooser_acts_in_evaluation_as_in_training(tiny_chooser: Path, tmp_path: Path) -> None:
    from policies.learned import PPOPolicy
    from train.choices import ChoicePoints
    from train.export import ExportArgs, export

    evals = np.load(tiny_chooser.parent / "eval" / "evaluations.npz")
    assert evals["content_share"].shape == (2, 2) and np.isfinite(evals["content_share"]).all()
    model = export(ExportArgs(tiny_chooser.parent, None, tmp_path / "m"))
    policy = PPOPolicy.load(model)
    spec = policy.residual.spec
    assert (policy.decision_hz, spec.decisions, spec.choice) == (500, "choices", "fill")
    split = WorldSplit.load(SPLIT)
    env = ChoicePoints(WorldEnv(split, "validation", {"decision_hz": 500}, 1), **_chooser_kwargs())
    obs, _ = env.reset()
    done = False
    while not done:
        r = policy.model(policy.normalizer.normalize_obs(obs[None, :])[0])
        obs, _, terminated, truncated, info = env.step(r)
        done = terminated or truncated
    seed = env.env.world["user_seed"]
    job = Job(f"ppo:{model}", f"s{seed}", seed, None, str(tmp_path), False, False, None,
              exercise="shoulder_extension", save_log=False,
              user_model=PerturbedUser(split.perturbations))  # fmt: skip
    row = run_episode(job)
    for key in ("content_share", "voice_natural", "em_mean_abs", "legs_in_step", "sm_max_abs"):
        assert _same(info[key], row[key]), key
    assert info["reward_legs"] == pytest.approx(_chooser_kwargs()["w_legs"] * info["legs_in_step"])
    assert float(_chooser_kwargs()["w_legs"]) > 0.0  # type: ignore[arg-type]


def test_the_reward_s_legs_in_step_is_the_evaluation_s() -> None:
    """A crafted session on a marked graph (legs out, back, again entered at 0, 3 and 6 s):
    ``session_legs`` measures as ``eval.legs`` does, from the timeline's utterances (vertex ids,
    times, a pause's length) and the graph's legs and kinds."""
    from collections import namedtuple

    from eval.episode import Utterance
    from eval.legs import leg_metrics
    from tests.test_legs_metric import _log
    from tests.test_script_legs import _graph
    from train.choices import session_legs

    graph = _graph()
    said = namedtuple("said", "phrase t_start t_end length", defaults=(None,))
    legs = ("out", "back", "again")
    cases = {  # (timeline, legs_in_step): "so" is a filler, "p" a pause, back's words late
        "in step": ([said("go", 0.0, 2.0), said("so", 2.9, 3.3), said("back", 3.4, 4.4),
                     said("more", 6.5, 8.0), said("done", 8.5, 9.5)], 1.0),
        "late": ([said("go", 0.0, 2.0), said("p", 2.0, 3.0, 1.0), said("so", 3.0, 3.6),
                  said("back", 4.2, 5.2), said("more", 6.5, 8.0)], 0.5),
        "unsaid": ([said("go", 0.0, 2.0), said("back", 3.4, 4.4)], 0.5),
    }  # fmt: skip
    leg_of = {u: graph.leg(u) for u in graph.phrases}
    for name, (timeline, want) in cases.items():
        log = _log(said=tuple(
            Utterance(u.phrase, "", u.t_start, u.t_end, u.length, u.phrase in graph.fillers,
                      leg_of[u.phrase] or "") for u in timeline
        ))  # fmt: skip
        assert log.leg is not None
        mine = session_legs(log.t, log.leg, timeline, graph, legs)
        theirs = leg_metrics(log)
        assert mine["legs_in_step"] == theirs["legs_in_step"] == want, name
        assert _same(mine["sm_max_abs"], theirs["sm_max_abs"]), name
    assert math.isnan(session_legs(log.t, log.leg, timeline, graph, ())["legs_in_step"])


def _chooser_kwargs() -> dict[str, object]:
    import yaml

    data = yaml.safe_load(SPLIT.read_text())
    (entry,) = data["LangCtrl-v0"]["env_wrapper"]
    return dict(entry["train.choices.ChoicePoints"])
