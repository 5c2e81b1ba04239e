"""Speech in step with every leg, measured: SM_k, sm_max_abs and legs_in_step (eval.legs), the
episode log that keeps what they need, and the figure and video that show them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eval.episode import EpisodeLog, EpisodeRecorder, Utterance
from eval.legs import (
    SM_TOLERANCE,
    first_words,
    graph_legs,
    leg_boundaries,
    leg_entries,
    leg_metrics,
)
from eval.metrics import METRIC_COLUMNS, episode_metrics
from langenv.errors import ConfigError

LEGS = ("out", "back", "again")


def _log(
    entries: tuple[float, ...] = (0.0, 3.0, 6.0),
    said: tuple[Utterance, ...] = (),
    *,
    names: tuple[str, ...] = LEGS,
    spoken: tuple[str, ...] = LEGS,
    end: float = 10.0,
    dt: float = 0.04,
    legs: bool = True,
) -> EpisodeLog:
    """A session of ``end`` s sampled every ``dt`` whose motion enters leg ``k`` at
    ``entries[k]`` (and is done at ``end``)."""
    t = np.arange(0.0, end + dt / 2, dt)
    leg = np.searchsorted(np.asarray(entries), t, side="right") - 1
    leg[t >= end] = len(entries)
    z = np.zeros_like(t)
    return EpisodeLog(
        "lc", "s0", t, z + 1.0, z, z + 1.0, z + 1.0, z, z, z, t >= end, t >= end,
        tuple(sorted(said, key=lambda u: u.t_start)), end, end, 0.0,
        leg=leg if legs else None, leg_names=names, spoken_legs=spoken,
    )  # fmt: skip


def _say(leg: str, t: float, *, filler: bool = False, pause: bool = False) -> Utterance:
    return Utterance(f"{leg}_{t}", "" if pause else "Words.", t, t + (0.0 if pause else 0.5),
                     0.5 if pause else None, filler, leg)  # fmt: skip


def test_each_leg_is_entered_where_its_index_first_reaches_it() -> None:
    t = np.arange(8) * 0.5
    leg = np.array([0, 0, 1, 1, 1, 2, 3, 3])  # 3: the last leg done
    assert leg_entries(t, leg, 3).tolist() == [0.0, 1.0, 2.5]
    assert np.isnan(leg_entries(t, np.zeros(8, int), 2)[1])  # never got there


def test_first_words_leave_fillers_pauses_and_other_legs_out() -> None:
    said = [_say("back", 3.0, filler=True), _say("back", 3.2, pause=True), _say("out", 3.4),
            _say("back", 4.0), _say("back", 5.0)]  # fmt: skip
    found = first_words(said, ["back", "again"])
    assert found["back"] == 4.0 and math.isnan(found["again"])


def test_sm_is_the_words_start_minus_the_leg_s_start() -> None:
    log = _log(said=(_say("out", 0.0), _say("back", 3.8), _say("again", 5.5)))
    found = leg_boundaries(log)
    assert [(b.leg, b.index) for b in found] == [("back", 1), ("again", 2)]
    assert found[0].t_enter == pytest.approx(3.0) and found[0].sm == pytest.approx(0.8)
    assert found[1].sm == pytest.approx(-0.5) and all(b.in_step for b in found)
    assert leg_metrics(log) == pytest.approx({"sm_max_abs": 0.8, "legs_in_step": 1.0})


def test_words_never_said_are_not_in_step_and_late_words_count_out() -> None:
    log = _log(said=(_say("out", 0.0), _say("back", 4.5)))  # again's words never said
    found = leg_boundaries(log)
    assert math.isnan(found[1].sm) and not found[1].in_step
    assert leg_metrics(log) == pytest.approx({"sm_max_abs": 1.5, "legs_in_step": 0.0})
    none = _log(said=(_say("out", 0.0),))
    m = leg_metrics(none)
    assert math.isnan(m["sm_max_abs"]) and m["legs_in_step"] == 0.0


def test_a_leg_without_words_is_no_boundary() -> None:
    log = _log(said=(_say("out", 0.0), _say("again", 6.2)), spoken=("out", "again"))
    assert [b.leg for b in leg_boundaries(log)] == ["again"]
    assert leg_metrics(log)["legs_in_step"] == 1.0


@pytest.mark.parametrize(
    "log",
    [
        _log(spoken=()),  # an unmarked graph
        _log(legs=False),  # a log without the motion's legs
        _log(names=()),
        _log(entries=(0.0,), names=("out",), spoken=("out",)),  # one leg: no boundary
    ],
    ids=["unmarked", "no-leg-trace", "no-leg-names", "one-leg"],
)
def test_no_boundary_no_figure(log: EpisodeLog) -> None:
    m = leg_metrics(log)
    assert leg_boundaries(log) == () and math.isnan(m["sm_max_abs"])
    assert math.isnan(m["legs_in_step"])


@settings(max_examples=60, deadline=None)
@given(
    gaps=st.lists(st.floats(0.5, 5.0), min_size=2, max_size=4),
    offsets=st.lists(st.one_of(st.none(), st.floats(-2.5, 3.0)), min_size=4, max_size=4),
    shift=st.floats(0.0, 20.0),
)
def test_sm_follows_its_definition(
    gaps: list[float], offsets: list[float | None], shift: float
) -> None:
    """On a 1 ms grid: SM_k is the words' start minus the leg's start (to the grid), the share
    in step counts |SM| <= 1 s (words never said: out), the largest |SM| is over the words said;
    shifting the whole session in time changes none of it."""
    names = tuple(f"leg{k}" for k in range(len(gaps) + 1))
    dt = 0.001
    starts = np.round(np.concatenate([[0.0], np.cumsum(gaps)]) / dt) * dt
    end = float(starts[-1] + 5.0)
    said = [Utterance("first", "Go.", 0.0, 0.5, leg=names[0])]
    for k in range(1, len(names)):
        off = offsets[k - 1]
        if off is not None:
            at = max(0.0, float(starts[k]) + off)
            said.append(Utterance(f"w{k}", "Words.", at, at + 0.3, leg=names[k]))
    base = _log(tuple(starts), tuple(said), names=names, spoken=names, end=end, dt=dt)
    moved = EpisodeLog(
        "lc", "s0", base.t + shift, base.cooperation, base.hand_speed, base.p, base.a,
        base.t_x, base.t_a, base.em, base.motion_done, base.speech_done,
        tuple(Utterance(u.phrase, u.text, u.t_start + shift, u.t_end + shift, leg=u.leg)
              for u in base.utterances),
        end + shift, end + shift, 0.0, leg=base.leg, leg_names=names, spoken_legs=names,
    )  # fmt: skip
    found = leg_boundaries(base)
    want = {u.leg: u.t_start - float(starts[names.index(u.leg)]) for u in said[1:]}
    for b in found:
        if b.leg in want:
            assert b.sm == pytest.approx(want[b.leg], abs=1.5 * dt)
        else:
            assert math.isnan(b.sm) and not b.in_step
    m, m2 = leg_metrics(base), leg_metrics(moved)
    sms = [b.sm for b in found]
    assert m["legs_in_step"] == sum(abs(x) <= SM_TOLERANCE for x in sms) / len(found)
    finite = [abs(x) for x in sms if not math.isnan(x)]
    assert (math.isnan(m["sm_max_abs"]) and not finite) or m["sm_max_abs"] == max(finite)
    assert m2["legs_in_step"] == m["legs_in_step"]
    assert (math.isnan(m["sm_max_abs"]) and math.isnan(m2["sm_max_abs"])) or m2[
        "sm_max_abs"
    ] == pytest.approx(m["sm_max_abs"], abs=1e-6)


def test_the_session_row_ends_with_the_leg_metrics_then_the_person_s() -> None:
    """Metrics are added at the end (the bootstrap of summary.md draws in column order): the leg
    metrics, then the path error and the effort (issue 46)."""
    row = episode_metrics(_log(said=(_say("out", 0.0), _say("back", 3.5), _say("again", 6.2))))
    assert list(row) == list(METRIC_COLUMNS) and METRIC_COLUMNS[-4:] == (
        "sm_max_abs", "legs_in_step", "path_error", "effort"
    )  # fmt: skip
    assert row["sm_max_abs"] == pytest.approx(0.5) and row["legs_in_step"] == 1.0


def test_the_log_keeps_its_legs_through_a_file(tmp_path: Path) -> None:
    log = _log(said=(_say("out", 0.0), _say("back", 3.5, filler=True), _say("back", 3.9)))
    back = EpisodeLog.load_npz(log.save_npz(tmp_path / "x.npz"))
    assert back.leg is not None and log.leg is not None
    assert np.array_equal(back.leg, log.leg) and back.leg.dtype == np.int64
    assert back.leg_names == LEGS and back.spoken_legs == LEGS
    assert [u.leg for u in back.utterances] == ["out", "back", "back"]
    assert leg_metrics(back) == leg_metrics(log)


def test_a_log_of_the_format_before_legs_reads_without_them(tmp_path: Path) -> None:
    log = _log(said=(_say("out", 0.0),))
    path = log.save_npz(tmp_path / "x.npz")
    with np.load(path) as data:
        old = {k: data[k] for k in data.files if k not in ("leg", "leg_names", "spoken_legs",
                                                          "utt_leg")}  # fmt: skip
    old["format"] = np.array(2)
    np.savez(tmp_path / "old.npz", **old)
    back = EpisodeLog.load_npz(tmp_path / "old.npz")
    assert back.leg is None and back.leg_names == () and back.utterances[0].leg == ""
    assert math.isnan(leg_metrics(back)["legs_in_step"])


@pytest.mark.parametrize(
    ("leg", "message"),
    [
        (np.array([0, 1, 0]), "never decrease"),
        (np.array([0, -1, 0]), ">= 0"),
        (np.array([0, 1]), "leg indices like t"),
    ],
)
def test_a_bad_leg_trace_is_refused(leg: np.ndarray, message: str) -> None:
    t = np.arange(3.0)
    z = np.zeros(3)
    with pytest.raises(ConfigError, match=message):
        EpisodeLog("lc", "s", t, z, z, z, z, z, z, z, z > 1, z > 1, (), 1.0, 1.0, 0.0, leg=leg)


def _info(t: float, leg: int) -> dict[str, float | int | bool | str]:
    return {"time": t, "cooperation": 1.0, "hand_speed": 0.0, "p": 1.0, "a": 1.0, "t_x": 1.0,
            "t_a": 1.0, "em": 0.0, "motion_done": False, "speech_done": False, "leg": leg,
            "phrase": "go"}  # fmt: skip


def test_the_recorder_keeps_the_leg_of_each_sample_and_each_utterance() -> None:
    rec = EpisodeRecorder("lc", "s0")
    rec.append(_info(0.0, 0))
    two = {k: np.array([v, v]) for k, v in _info(0.5, 1).items() if k != "phrase"}
    two["time"] = np.array([0.5, 1.0])
    rec.extend(two, "go")
    rec.append(_info(1.5, 2))
    said = [Utterance("go", "", 0.0, 0.4), Utterance("back", "", 0.6, 1.0)]
    log = rec.build(0.0, t_motion=1.5, t_speech=1.5, utterances=said,
                    leg_of={"go": "out", "back": "back"}, leg_names=LEGS,
                    spoken_legs=("out", "back"))  # fmt: skip
    assert log.leg is not None and log.leg.tolist() == [0, 1, 1, 2]
    assert [u.leg for u in log.utterances] == ["out", "back"]
    partial = EpisodeRecorder("lc", "s0")
    partial.append(_info(0.0, 0))
    partial.append({k: v for k, v in _info(0.5, 1).items() if k != "leg"})
    with pytest.raises(ConfigError, match="'leg' in 1 of 2 samples"):
        partial.build(0.0, t_motion=0.5, t_speech=0.5)


def test_a_graph_s_legs_as_the_log_keeps_them() -> None:
    from tests.test_script_legs import _graph

    leg_of, spoken = graph_legs(_graph())
    assert spoken == LEGS and leg_of["more#2"] == "again" and leg_of["go"] == "out"
    assert graph_legs(_graph(legs=(), leg_of={})) == ({}, ())


def test_the_session_figure_shades_the_legs_and_marks_each_sm(tmp_path: Path) -> None:
    from eval.plots import _IN_STEP, _OUT_OF_STEP, session_figure
    from tests.test_plots import has_colour

    said = (_say("out", 0.0), _say("back", 3.4), _say("again", 8.5))  # in step, then 2.5 s late
    marked = session_figure(_log(said=said), tmp_path / "legs.png")
    plain = session_figure(_log(said=said, legs=False), tmp_path / "plain.png")
    assert has_colour(marked, _IN_STEP) and has_colour(marked, _OUT_OF_STEP)
    assert not has_colour(plain, _IN_STEP) and not has_colour(plain, _OUT_OF_STEP)
    assert has_colour(marked, "#DADADA", 2000) and not has_colour(plain, "#DADADA", 2000)


def test_the_session_video_names_the_current_leg() -> None:
    from eval.video import CAPTION_HEIGHT, FRAME_SIZE, _Captions

    said = (Utterance("long", "A long line said over two legs.", 1.0, 5.0, leg="out"),)
    log = _log(said=said)
    band = _Captions(log, (FRAME_SIZE[0], CAPTION_HEIGHT))
    assert [band.leg_label(t) for t in (2.0, 4.0, 7.0, 10.0)] == [
        "leg 1/3: out", "leg 2/3: back", "leg 3/3: again", "legs done"
    ]  # fmt: skip
    assert not np.array_equal(band.frame(2.0), band.frame(4.0))  # the same caption, another leg
    plain = _Captions(_log(said=said, legs=False), (FRAME_SIZE[0], CAPTION_HEIGHT))
    assert plain.leg_label(4.0) == "" and np.array_equal(plain.frame(2.0), plain.frame(4.0))


def test_compare_writes_the_leg_metrics_and_the_verdict_shows_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from eval.report import read_sessions_csv
    from langctrl.jobs.compare import main

    out = tmp_path / "c"
    args = ["--policies", "ac,lc", "--users", "synthetic:1", "--workers", "1", "--seed", "5"]
    assert main([*args, "--out", str(out)]) == 0
    assert "legs in step %" in capsys.readouterr().out
    rows = {r["policy"]: r for r in read_sessions_csv(out / "sessions.csv")}
    assert math.isnan(float(rows["ac"]["legs_in_step"]))  # one wording, no marks
    assert 0.0 <= float(rows["lc"]["legs_in_step"]) <= 1.0  # the default graph is marked
    log = EpisodeLog.load_npz(out / "sessions" / "lc_s5.npz")
    assert log.leg_names == LEGS and log.spoken_legs == LEGS and log.leg is not None
    assert {u.leg for u in log.utterances} == set(LEGS)
    assert leg_metrics(log)["legs_in_step"] == float(rows["lc"]["legs_in_step"])
