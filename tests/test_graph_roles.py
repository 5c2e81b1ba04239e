"""Every policy speaks the exercise's words (issue 37): graph roles, the graph each policy speaks,
a learned model fitted to it (padded, widened or refused), and the graph named in every table."""

from __future__ import annotations

import csv
import dataclasses
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import langenv
from eval.compare import main
from eval.episode import EpisodeLog
from eval.report import mixed_graph_policies
from eval.verdict import verdict_table
from langenv.errors import ConfigError, GraphChoicesError
from langenv.exercise import resolve_exercise
from langenv.exercise.script import (
    ASSETS_DIR,
    SpokenGraph,
    graph_label,
    graph_role,
    speak,
    spoken_graph,
)
from langenv.speech.graph import PhraseGraph, graph_path
from policies import load_policy
from policies.analytic import LanguageController
from policies.learned import PPOPolicy, ResidualLC, ResidualSpec

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "models" / "ppo_aligner.zip"  # trained on the study's graph: 6 choices
H2M_LC = "exercises/scripts/hand_to_mouth_lc.yaml"
FAST = ["--workers", "1", "--no-audio", "--no-figures"]


def test_policies_declare_a_role_not_a_file() -> None:
    roles = {s: graph_role(load_policy(s)) for s in ("ac", "lc-noap", "lc", "lc-em-end")}
    assert roles == {"ac": "single", "lc-noap": "single", "lc": "graph", "lc-em-end": "graph"}
    assert graph_role(load_policy(f"ppo:{SHIPPED}")) == "graph"
    with pytest.raises(ConfigError, match="graph_role"):
        LanguageController(graph_role="study")

    class Legacy:  # a policy of the interface before roles: its phrase_graph says the role
        name, phrase_graph, decision_hz = "old", "ac", 25

    assert graph_role(Legacy()) == "single"
    Legacy.phrase_graph = "my/own.yaml"  # its own file is not spoken: the exercise's graph is
    assert graph_role(Legacy()) == "graph"


def test_the_exercise_maps_the_role_to_its_graph() -> None:
    assert (spoken_graph("graph").label, spoken_graph("single").label) == ("default", "lc-noap")
    h2m = spoken_graph("graph", "hand_to_mouth")
    assert (h2m.label, h2m.max_children, h2m.overridden) == (H2M_LC, 9, False)
    assert spoken_graph("single", "hand_to_mouth").label.endswith("hand_to_mouth_single.yaml")
    study = spoken_graph("graph", "hand_to_mouth", override="study")
    assert (study.label, study.max_children, study.overridden) == ("study", 6, True)
    with pytest.raises(ConfigError, match="one wording"):
        spoken_graph("single", None, override="study")
    with pytest.raises(ConfigError, match="graph role"):
        resolve_exercise(None).graph_for("script")


def test_graph_labels_name_no_path_of_the_machine(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert [graph_label(g) for g in ("lc", "default", "ac", "lc_noap", "study")] == [
        "default",
        "default",
        "lc-noap",
        "lc-noap",
        "study",
    ]
    assert graph_label(ASSETS_DIR / H2M_LC) == H2M_LC
    assert graph_label("graphs/mine.yaml") == "graphs/mine.yaml"  # relative: as given
    monkeypatch.chdir(tmp_path)
    assert graph_label(tmp_path / "sub" / "g.yaml") == "sub/g.yaml"  # under the cwd
    assert graph_label("/elsewhere/deep/g.yaml") == "g.yaml"  # outside it: the file name


def _actions(policy: PPOPolicy, graph: str, seed: int = 3, steps: int = 200) -> np.ndarray:
    env = gym.make(
        langenv.ENV_ID, phrase_graph=graph, decision_hz=policy.decision_hz, **policy.env_kwargs
    )
    obs, _ = env.reset(seed=seed)
    policy.reset()
    acts = []
    for _ in range(steps):
        acts.append(policy.act(obs))
        obs, _, term, trunc, _ = env.step(acts[-1])
        if term or trunc:
            break
    return np.array(acts)


def test_a_model_is_widened_as_train_widen_widens_it(tmp_path: Path) -> None:
    """On the study's exercise the shipped model (6 choices) speaks the default graph (9): it is
    widened in memory, acting exactly as the model python -m train.widen writes."""
    from train.widen import widen

    policy = PPOPolicy.load(SHIPPED)
    assert (policy.trained_graph, policy.max_children) == ("study", 6)
    spoken = speak(policy)
    assert (spoken.label, policy.widened_from, policy.max_children) == ("default", 6, 9)
    assert policy.env_kwargs["max_children"] == 9
    on_disk = PPOPolicy.load(widen(SHIPPED, 9, tmp_path / "wide"))
    speak(on_disk)
    assert on_disk.widened_from is None  # already 9 wide: nothing to do
    np.testing.assert_array_equal(_actions(policy, spoken.ref), _actions(on_disk, spoken.ref))


def test_a_model_reads_a_graph_of_fewer_choices_with_empty_blocks(tmp_path: Path) -> None:
    graph = tmp_path / "two.yaml"
    graph.write_text(
        "start: a\nphrases:\n  a: {text: Move your hand out., next: [b, c]}\n"
        "  b: {text: And back., next: []}\n  c: {text: And slowly back now., next: []}\n"
    )
    policy = PPOPolicy.load(SHIPPED)
    spoken = speak(policy, override=str(graph))
    assert (spoken.max_children, policy.max_children, policy.widened_from) == (2, 6, None)
    assert policy.env_kwargs["max_children"] == 6  # the observation keeps the model's layout
    assert len(_actions(policy, spoken.ref, steps=50)) == 50


def test_a_model_that_cannot_act_on_the_graph_is_refused_by_name() -> None:
    policy = PPOPolicy.load(SHIPPED)
    spec = ResidualSpec(choice_mode="scores", max_children=6, decision_hz=25)
    scores = dataclasses.replace(policy, residual=ResidualLC(spec))
    with pytest.raises(GraphChoicesError) as err:
        speak(scores, "hand_to_mouth")
    exc = err.value
    assert (exc.graph, exc.model_choices, exc.graph_choices) == (H2M_LC, 6, 9)
    text = str(exc)
    assert "ppo_aligner.zip" in text and H2M_LC in text and "python -m train.ppo" in text
    assert isinstance(exc, ValueError)  # the package's errors are ValueErrors where they can be


def test_changed_training_graph_warns_only_when_spoken() -> None:
    policy = PPOPolicy.load(SHIPPED)
    policy.trained_digest = "0" * 64  # as if study.yaml changed since training
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        speak(policy)  # another graph than the training one: nothing to warn about
    with pytest.warns(UserWarning, match="changed since"):
        speak(policy, override="study")


def _rows(out: Path) -> list[dict[str, str]]:
    return list(csv.DictReader((out / "sessions.csv").open()))


def test_learned_policy_speaks_the_exercise_s_script(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The issue's run: on hand_to_mouth the learned model spoke the study's external-rotation
    script; now it speaks hand_to_mouth's, and sessions.csv and the table say so."""
    out = tmp_path / "h2m"
    args = ["--exercise", "hand_to_mouth", "--policies", f"lc,ppo:{SHIPPED}"]
    assert main([*args, "--users", "synthetic:1", "--out", str(out), *FAST]) == 0
    std = capsys.readouterr()
    rows = _rows(out)
    assert [(r["policy"], r["graph"], r["graph_role"]) for r in rows] == [
        ("lc", H2M_LC, "graph"),
        ("ppo", H2M_LC, "graph"),
    ]
    h2m = PhraseGraph.load(graph_path(ASSETS_DIR / H2M_LC))
    study = PhraseGraph.load(graph_path("study"))
    log = EpisodeLog.load_npz(out / "sessions" / "ppo_s0.npz")
    said = {u.phrase for u in log.utterances}
    assert said and said <= set(h2m.phrases) and not said & {"intro", "slide", "glide"}
    texts = " ".join(h2m.phrases[u].text or "" for u in said)
    assert "away from your body" not in texts and "intro" in study.phrases
    assert "widened" in std.err and "trained on study" in std.err
    assert H2M_LC in std.out and "\u2020" not in std.out
    assert f"PPO `{H2M_LC}`" in (out / "summary.md").read_text()


def test_mixed_graphs_need_the_flag_and_are_marked(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "mixed"
    args = ["--policies", "lc,lc-em", "--graph", "lc-em=study", "--users", "synthetic:1"]
    assert main([*args, "--out", str(out), *FAST]) == 2
    err = capsys.readouterr().err
    assert "lc speaks default" in err and "lc-em speaks study" in err
    assert "--allow-mixed-graphs" in err and not out.exists()
    assert main([*args, "--allow-mixed-graphs", "--out", str(out), *FAST]) == 0
    std = capsys.readouterr().out
    assert {(r["policy"], r["graph"]) for r in _rows(out)} == {
        ("lc", "default"),
        ("lc-em", "study"),
    }
    assert "default \u2020" in std and "study \u2020" in std and "compare scripts" in std
    summary = (out / "summary.md").read_text()
    assert "Mixed graphs" in summary and "LC-EM \u2020" in summary
    # AC and LC-noAP saying one wording beside LC is the paper's comparison: not mixed
    assert (
        main(["--policies", "ac,lc", "--users", "synthetic:1", "--out", str(tmp_path / "p"), *FAST])
        == 0
    )
    assert "\u2020" not in capsys.readouterr().out


def test_graph_overrides_are_checked_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "x"
    for extra, message in (
        (["--policies", "ac,lc", "--graph", "ac=study"], "one wording"),
        (["--policies", "lc", "--graph", "nobody=study"], "POLICY=GRAPH needs a POLICY"),
    ):
        assert main([*extra, "--out", str(out), *FAST]) == 2
        assert message in capsys.readouterr().err
    for extra in (
        ["--policies", "lc", "--graph", "study", "--graph", "lc-noap"],
        ["--policies", "lc,lc-em", "--graph", "lc=study", "--graph", "lc=default"],
    ):
        with pytest.raises(SystemExit) as stop:  # argparse's usage error
            main([*extra, "--out", str(out), *FAST])
        assert stop.value.code == 2 and "two graphs" in capsys.readouterr().err
    assert not out.exists()


def test_tables_mark_only_a_role_spoken_with_several_graphs() -> None:
    def row(policy: str, graph: str, role: str) -> dict[str, object]:
        return {"policy": policy, "user": "s0", "graph": graph, "graph_role": role}

    paper = [row("ac", "lc-noap", "single"), row("lc-noap", "lc-noap", "single")]
    paper.append(row("lc", "default", "graph"))
    assert mixed_graph_policies(paper, ["ac", "lc-noap", "lc"]) == []
    mixed = [*paper, row("ppo", "study", "graph")]
    assert mixed_graph_policies(mixed, ["ac", "lc-noap", "lc", "ppo"]) == ["lc", "ppo"]
    assert mixed_graph_policies([{"policy": "lc", "user": "s0"}], ["lc"]) == []  # older table


def test_verdict_and_summary_name_the_graph() -> None:
    rows = [
        {"policy": p, "user": f"s{u}", "abs_am": 0.1 * u, "em_mean_abs": 0.2, "a_dev": 0.1,
         "graph": g, "graph_role": r}
        for p, g, r in (("ac", "lc-noap", "single"), ("lc", "default", "graph"))
        for u in range(3)
    ]  # fmt: skip
    header, body = verdict_table(rows, ["ac", "lc"])
    assert header[-1] == "graph" and [b[-1] for b in body] == ["lc-noap", "default"]
    assert "graph" not in verdict_table([{k: v for k, v in r.items() if "graph" not in k}
                                         for r in rows], ["ac", "lc"])[0]  # fmt: skip


def test_play_and_the_robot_loop_speak_the_exercise_s_graph(tmp_path: Path) -> None:
    from langctrl.jobs.play import main as play_main

    wav = tmp_path / "x.wav"
    args = ["--headless", "--seconds", "1", "--audio-out", str(wav)]
    assert play_main(["--policy", "ac", "--graph", "study", *args]) == 2  # one wording: refused
    assert not wav.exists()
    from langenv.live.registry import load_registered_policy
    from langenv.live.robot_loop import RobotLoop
    from langenv.robot.sim_io import MujocoRobot

    robot = MujocoRobot(realtime=False, seed=0)
    policy = load_registered_policy(f"ppo:{SHIPPED}")
    loop = RobotLoop(robot, policy, exercise="hand_to_mouth")
    assert isinstance(loop.spoken, SpokenGraph) and loop.spoken.label == H2M_LC
    assert loop.env.max_children == policy.max_children == 9
