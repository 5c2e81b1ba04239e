"""Speech in step with every leg (``langenv/speech/legs.py``): segments, gates, plans to a leg's
end, the motion's time to each leg's end, their compiled twins, and the law in the env."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.env import LangCtrlEnv
from langenv.errors import ConfigError, PhraseGraphError
from langenv.speech.graph import GRAPHS_DIR, PhraseGraph
from langenv.speech.graph_kernels import eta as compiled_eta
from langenv.speech.graph_kernels import fill as compiled_fill
from langenv.speech.legs import LegPlan
from langenv.speech.legs_kernels import horizon as compiled_horizon
from langenv.speech.legs_kernels import motion_segment as compiled_motion_segment
from langenv.speech.phrase import Phrase
from langenv.speech.repeat import WAIT_MAX, WAIT_PLAN
from langenv.speech.timeline import SpeechTimeline
from policies.analytic import make_analytic

LEGS = ("out", "back", "again")


def three_legs(**kw: Any) -> PhraseGraph:
    """intro, a pause, optional lines (out); a filler and a line, an optional line, a pause
    (back); two lines (again)."""
    phrases = [
        Phrase("intro", "Move out.", None, ("p1",)),
        Phrase("p1", None, None, ("opt1", "opt2", "okay", "ret"), "pause", (0.2, 0.8)),
        Phrase("opt1", "Glide.", None, ("okay", "ret")),
        Phrase("opt2", "Glide smoothly.", None, ("okay", "ret")),
        Phrase("okay", "Okay", None, ("ret",), "filler"),
        Phrase("ret", "Come back.", None, ("opt3", "p2")),
        Phrase("opt3", "Nice and easy.", None, ("p2",)),
        Phrase("p2", None, None, ("one",), "pause", (0.2, 0.8)),
        Phrase("one", "One more.", None, ("done",)),
        Phrase("done", "Done.", None, ()),
    ]
    dur = {"intro": 2.0, "opt1": 1.5, "opt2": 2.5, "okay": 0.4, "ret": 1.8, "opt3": 1.2,
           "one": 1.0, "done": 0.8}  # fmt: skip
    leg_of = dict.fromkeys(("intro", "p1", "opt1", "opt2"), "out")
    leg_of |= dict.fromkeys(("okay", "ret", "opt3", "p2"), "back")
    leg_of |= {"one": "again", "done": "again"}
    args: dict[str, Any] = {"pause": 0.25, "final_wait": True, "legs": LEGS, "leg_of": leg_of}
    return PhraseGraph(phrases, "intro", dur, **(args | kw))


# ------------------------------------------------------------------------------ structure
def test_gates_sit_between_legs() -> None:
    g = three_legs()
    assert g.segment_names == LEGS and g.segments == 3
    # the words of leg back are reached through one gate, a silence of leg out
    assert g.children("p1") == ("opt1", "opt2", "back#gate")
    assert g.children("opt1") == ("back#gate",)
    assert g.children("back#gate") == ("okay", "ret")
    assert g.is_gate("back#gate") and g.segment("back#gate") == 0
    assert g.choice_segment("back#gate") == 1 and g.choice_segment("p1") == 0
    # a pause whose children all begin the next leg is itself the gate, opened above
    assert g.is_gate("p2") and g.children("p2") == ("one",) and "again#gate" not in g.phrases
    assert g.slot_range("p2") == (0.2, WAIT_MAX) and g.plan_range("p2") == (0.2, 0.8)
    assert g.slot_range("back#gate") == (0.0, WAIT_MAX)
    assert g.plan_range("back#gate") == (0.0, WAIT_PLAN)
    assert [g.leg(u) for u in ("intro", "back#gate", "okay", "p2", "one", "done#wait")] == [
        "out", "out", "back", "back", "again", "again"
    ]  # fmt: skip
    # every edge from one segment to the next leaves a gate
    for u in g.phrases:
        for v in g.children(u):
            assert g.segment(v) == g.segment(u) or (
                g.is_gate(u) and g.segment(v) == g.segment(u) + 1
            )


def test_plans_stop_at_a_legs_end_and_the_whole_speech_is_kept() -> None:
    g = three_legs()
    # opt1: its clip and pause, then the gate (planned 0 to WAIT_PLAN): the end of leg out
    assert g.t_min("opt1") == pytest.approx(1.75)
    assert g.t_max("opt1") == pytest.approx(1.75 + WAIT_PLAN)
    assert g.t_min("back#gate") == 0.0 and g.t_max("back#gate") == WAIT_PLAN
    assert g.t_min("ret") == pytest.approx(2.05 + 0.2)  # ret, then the gate p2 at least
    lo, hi = g.speech_range()
    assert lo == pytest.approx(2.25 + 0.2 + 0.0 + 2.05 + 0.2 + 1.25 + 0.8)
    assert hi > g.t_max("intro")


def test_an_unmarked_graph_is_one_segment_as_before() -> None:
    g = three_legs(legs=(), leg_of={})
    assert g.segments == 1 and g.segment_names == () and g.leg("ret") is None
    assert not any(g.is_gate(u) for u in g.phrases)
    assert g.speech_range() == (g.t_min("intro"), g.t_max("intro"))
    assert g.eta("intro", 1.0, 9.0) == g.eta("intro", 1.0, [9.0])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"legs": ("out", "back")}, "leg 'again' is not one of"),
        ({"legs": ("out", "out", "again")}, "'legs' must be distinct"),
        ({"leg_of": {"intro": "out"}}, "no 'leg'"),
        ({"legs": ()}, "have a 'leg' but the graph lists no 'legs'"),
    ],
)
def test_bad_legs_are_named(change: dict[str, Any], message: str) -> None:
    with pytest.raises(PhraseGraphError, match=re.escape(message)):
        three_legs(**change)


def test_legs_follow_in_order_and_a_leg_cannot_be_passed_by() -> None:
    g = three_legs()
    back = dict(g.leg_of) | {"one": "out"}
    with pytest.raises(PhraseGraphError, match=r"leads back to 'one'.*legs follow"):
        three_legs(leg_of=back)
    skip = dict(g.leg_of) | {"okay": "again", "ret": "again", "opt3": "again", "p2": "again"}
    # back's words now skipped from leg out: its only words are none; make 'out' lead to again
    with pytest.raises(PhraseGraphError, match="passing by the words of leg"):
        three_legs(legs=("out", "back", "again"), leg_of=skip | {"opt1": "back"})


def test_a_graph_file_records_its_legs(tmp_path: Path) -> None:
    path = tmp_path / "g.yaml"
    path.write_text(
        "start: a\npause: 0.25\nlegs: [out, back]\nphrases:\n"
        "  a: {text: 'Go out.', next: [b], leg: out}\n"
        "  b: {text: 'Come back.', next: [], leg: back}\n",
        encoding="utf-8",
    )
    g = PhraseGraph.load(path)
    assert g.legs == ("out", "back") and g.leg("b") == "back"
    assert g.children("a") == ("back#gate",) and g.with_voice("natural").legs == g.legs
    path.write_text(
        "start: a\nlegs: out\nphrases:\n  a: {text: 'Go.', next: [], leg: 3}\n", encoding="utf-8"
    )
    with pytest.raises(PhraseGraphError) as err:
        PhraseGraph.load(path)
    assert "'legs' must be a list of leg names" in str(err.value)
    assert "'leg' must be a leg name" in str(err.value)


# ------------------------------------------------------------------------------ horizons
def test_horizons_of_a_plan() -> None:
    plan = LegPlan((0, 2, 3), (7.0, 2.0, 0.0))
    assert plan.segments == 3 and [plan.motion_segment(k) for k in range(5)] == [0, 1, 1, 2, 2]
    assert plan.horizons(12.0, 1.5, 0) == (1.5, 10.0, 12.0)  # in leg 0; leg 1 and 2 ahead
    assert plan.horizons(6.0, 0.5, 1) == (0.0, 4.0, 6.0)  # past segment 0
    assert plan.horizons(2.5, 1.0, 2) == (0.0, 1.0, 2.5)
    assert plan.horizons(3.0, 2.0, 1) == (0.0, 2.0, 3.0)  # never below the leg's own time
    assert LegPlan.whole(3).horizons(9.0, 2.0, 1) == (9.0,)
    for bad in (((), ()), ((1, 1), (0.0, 0.0)), ((0, 1), (-1.0, 0.0)), ((0,), (0.0, 1.0))):
        with pytest.raises(ConfigError):
            LegPlan(*bad)


@settings(max_examples=200, deadline=None)
@given(
    t_x=st.floats(0.0, 60.0),
    t_leg=st.floats(0.0, 20.0),
    leg=st.integers(0, 4),
)
def test_the_compiled_horizons_are_the_plans(t_x: float, t_leg: float, leg: int) -> None:
    plan = LegPlan((0, 2, 3), (7.0, 2.0, 0.0))
    lg = plan.packed([0, 1], [False, True])
    assert compiled_motion_segment(lg, leg) == plan.motion_segment(leg)
    for j, h in enumerate(plan.horizons(t_x, t_leg, leg)):
        assert compiled_horizon(lg, j, t_x, t_leg, leg) == h


@settings(max_examples=200, deadline=None)
@given(
    data=st.data(),
    t_x=st.floats(0.0, 40.0),
    t_leg=st.floats(0.0, 10.0),
    leg=st.integers(0, 2),
    remaining=st.floats(0.0, 3.0),
)
def test_the_compiled_plans_are_the_graphs(
    data: st.DataObject, t_x: float, t_leg: float, leg: int, remaining: float
) -> None:
    g = three_legs()
    plan = LegPlan((0, 1, 2), (6.0, 3.0, 0.0))
    order = g.order
    mid, slot, kid_ptr, kids = g.packed(order)
    lg = plan.packed([g.segment(u) for u in order], [g.is_gate(u) for u in order])
    hz = plan.horizons(t_x, t_leg, leg)
    u = data.draw(st.sampled_from(order))
    i = order.index(u)
    last = data.draw(st.integers(0, 2))
    assert compiled_eta(i, remaining, t_x, t_leg, leg, last, mid, slot, kid_ptr, kids, lg) == (
        g.eta(u, remaining, hz, last)
    )
    if u in g.pauses:
        target = hz[g.segment(u)]
        assert compiled_fill(i, target, mid, slot, kid_ptr, kids, lg) == g.pause_length(u, target)


def test_a_gates_length_is_the_motions_time_to_the_legs_end() -> None:
    g = three_legs()
    assert g.pause_length("back#gate", 3.7) == 3.7  # no words after it in its leg
    assert g.pause_length("back#gate", -1.0) == 0.0
    assert g.pause_length("p2", 0.1) == 0.2  # a pause that became the gate keeps its minimum


def test_a_gate_its_leg_has_passed_leaves_the_legs_first_words_to_the_next_step() -> None:
    """Words that run late reach a gate after its leg has begun: the gate ends with the step it
    begins in, and the leg's first words are the next step's choice (a policy's), not the rule's
    in the same step."""
    tl = SpeechTimeline(three_legs())
    asked: list[tuple[float, tuple[str, ...]]] = []

    def choose(kids: tuple[str, ...]) -> str:
        asked.append((tl.t, kids))
        return "opt1" if "opt1" in kids else "ret"

    hz = (0.0, 5.0, 8.0)  # the motion is in leg 'back' already
    while tl.phrase != "back#gate":
        tl.step(0.002, 1.0, choose, hz)
    entered = tl.t
    assert [kids for _, kids in asked] == [("opt1", "opt2", "back#gate")]
    assert tl.in_pause and tl.remaining_in_phrase == 0.0
    tl.step(0.002, 1.0, choose, hz)
    assert asked[-1] == (pytest.approx(entered), ("okay", "ret"))
    assert tl.phrase == "ret"
    gate = [u for u in tl.utterances() if u.phrase == "back#gate"]
    assert len(gate) == 1 and gate[0].t_end - gate[0].t_start < 0.002


# ------------------------------------------------------------------------------ the env
def _marked_default(tmp_path: Path) -> Path:
    """The default graph (external_rotation's script) with each vertex's leg by its line: lines
    9-11 out, 12-14 back, from 15 again."""
    out = []
    for line in (GRAPHS_DIR / "default.yaml").read_text(encoding="utf-8").splitlines():
        if line.startswith("phrases:"):
            out.append("legs: [out, back, again]")
        out.append(line)
        m = re.match(r"^  (\S+):\s+# line (\d+)", line)
        if m:
            n = int(m.group(2))
            out.append(f"    leg: {'out' if n < 12 else 'back' if n < 15 else 'again'}")
    path = tmp_path / "default_legs.yaml"
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path


def test_a_marked_graph_on_another_exercise_is_named(tmp_path: Path) -> None:
    graph = _marked_default(tmp_path)
    with pytest.raises(ConfigError, match=r"leg 'out' is not a leg of exercise 'hand_to_mouth'"):
        LangCtrlEnv(exercise="hand_to_mouth", phrase_graph=graph)


@pytest.mark.portable
def test_compiled_ticks_are_the_python_ticks_on_a_marked_graph(tmp_path: Path) -> None:
    graph = _marked_default(tmp_path)
    fast = LangCtrlEnv(phrase_graph=graph, decision_hz=25, users="synthetic")
    ref = LangCtrlEnv(phrase_graph=graph, decision_hz=25, users="synthetic")
    ref._steps = None
    rng = np.random.default_rng(5)
    oa, _ = fast.reset(seed=7)
    ob, _ = ref.reset(seed=7)
    assert oa.tobytes() == ob.tobytes()
    for k in range(2000):
        act = rng.uniform(-0.6, 0.6, 3).astype(np.float32)
        a, b = fast.step(act), ref.step(act)
        assert a[0].tobytes() == b[0].tobytes(), f"step {k}"
        assert a[1:4] == b[1:4] and a[4] == b[4], f"step {k}"
        if a[2]:
            break
    assert a[2] and fast.speech.path == ref.speech.path
    assert any(fast.graph.is_gate(u) for u in fast.speech.path)


def _step_alignment(env: Any, policy: Any, seed: int) -> tuple[list[float], float]:
    obs, _ = env.reset(seed=seed)
    policy.reset()
    entered = {0: 0.0}
    done = False
    info: dict[str, Any] = {}
    while not done:
        obs, _, term, trunc, info = env.step(policy.act(obs))
        if env.motion.state.leg not in entered and not env.motion.state.done:
            entered[env.motion.state.leg] = info["time"]
        done = term or trunc
    first: dict[str, float] = {}
    for utt in env.speech.utterances():
        leg = env.graph.leg(utt.phrase)
        if env.graph.kind(utt.phrase) == "phrase" and leg not in first:
            first[leg] = utt.t_start
    names = env.exercise.leg_names
    return [first[names[k]] - entered[k] for k in range(1, len(names))], info["am"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["lc", "lc-fill-end"])
def test_each_legs_words_start_with_the_leg(tmp_path: Path, name: str) -> None:
    graph = _marked_default(tmp_path)
    policy = make_analytic(name)
    env = LangCtrlEnv(phrase_graph=graph, decision_hz=policy.decision_hz, users="synthetic")
    for seed in (11, 12, 13):
        sm, am = _step_alignment(env, policy, seed)
        assert all(abs(x) <= 1.0 for x in sm), (seed, sm)
        assert abs(am) <= 1.0


THERAPIST = Path(__file__).parent / "data" / "exercises" / "therapist"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("exercise", "script"),
    [
        ("external_rotation", "external_rotation_lc.yaml"),
        ("hand_to_mouth", "hand_to_mouth_lc.yaml"),
        (str(THERAPIST / "reach.yaml"), "reach_lc.yaml"),
    ],
)
def test_a_therapists_script_is_in_step_at_every_leg(exercise: str, script: str) -> None:
    # one block of lines per leg, no fillers (tests/data/exercises/therapist/*.txt)
    policy = make_analytic("lc")
    env = LangCtrlEnv(
        exercise=exercise, phrase_graph=THERAPIST / script, decision_hz=500, users="synthetic"
    )
    for seed in (21, 22):
        sm, am = _step_alignment(env, policy, seed)
        assert all(abs(x) <= 1.0 for x in sm) and abs(am) <= 1.0, (seed, sm)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.floats(0.0, 30.0), min_size=1, max_size=40),
    st.integers(0, 39),
)
def test_tracking_many_observations_is_tracking_each(values: list[float], cut: int) -> None:
    times = [0.002 * k for k in range(len(values))]
    one, many = make_analytic("lc-fill"), make_analytic("lc-fill")
    for t_x, now in zip(values, times, strict=True):
        one.track(t_x, now)
    k = min(cut, len(values))
    for t_x, now in zip(values[:k], times[:k], strict=True):
        many.track(t_x, now)
    many.track_many(np.array(values[k:]), np.array(times[k:]))
    assert (one._t_x0, one._used, one._leg_t0, one._prev_t_x) == (
        many._t_x0,
        many._used,
        many._leg_t0,
        many._prev_t_x,
    )


def test_a_script_variant_keeps_its_legs(tmp_path: Path) -> None:
    from langenv.speech.variant import GraphVariation, vary_graph

    graph = PhraseGraph.load(_marked_default(tmp_path))
    rng = np.random.default_rng(3)
    for _ in range(5):
        out = vary_graph(graph, rng, GraphVariation(p_drop=0.3, p_add=0.3))
        assert out.legs == graph.legs and out.segment_names == graph.segment_names
        assert all(out.leg(u) in graph.legs for u in out.phrases)


def test_a_plan_maps_segments_to_the_exercises_legs() -> None:
    from types import SimpleNamespace

    from langenv.speech.legs import leg_plan

    names = ("out", "back", "again", "rest")
    rests = {0: 9.0, 1: 6.0, 2: 3.0}

    def plan(*legs: str) -> LegPlan:
        graph = SimpleNamespace(segment_names=legs, legs=legs, path=Path("g.yaml"))
        return leg_plan(graph, names, rests.__getitem__, "ex")

    # a leg without words is spoken about by the segment before it; the first starts the motion
    assert plan("out", "again") == LegPlan((1, 3), (6.0, 0.0))
    assert plan("back", "rest") == LegPlan((2, 3), (3.0, 0.0))
    assert plan() == LegPlan.whole(4)
    with pytest.raises(ConfigError, match=r"g.yaml: leg 'up' is not a leg of exercise 'ex'"):
        plan("out", "up")
    with pytest.raises(ConfigError, match="not in the order of exercise 'ex'"):
        plan("again", "out")
