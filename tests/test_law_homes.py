"""Each of the paper's laws has one home: one Python reference and one compiled twin, named
alike and side by side (``X.py`` and ``X_kernels.py`` in the package that owns the law), the twin
equal to its reference on random inputs, to the bit; and the constants the laws share are
assigned in one file each (docs/ARCHITECTURE.md, "Where the paper's equations live").

The whole episodes the twins make are held to their Python references elsewhere
(``tests/test_compiled_tick.py``, ``test_compiled_steps.py``, ``test_pace_law.py``,
``test_train_batched.py``, ``test_pinned_episodes.py``); here each law on its own.
"""

from __future__ import annotations

import importlib
import math
import re
import struct
from dataclasses import dataclass
from functools import reduce
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.control import admittance_kernels as admittance_k
from langenv.control import motion_etc, pacing
from langenv.control import motion_etc_kernels as motion_etc_k
from langenv.control import pacing_kernels as pacing_k
from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.guide import Guide
from langenv.control.trajectory import default_exercise
from langenv.kernels import mjc
from langenv.speech import choice
from langenv.speech import choice_kernels as choice_k
from langenv.speech.graph import PhraseGraph
from langenv.task import reward
from langenv.task import reward_kernels as reward_k
from langenv.task.observation import T_SCALE
from tests.compiled_graph import c_eta, c_fill
from tests.test_graph_pauses import pause_dags

Vec3 = tuple[float, float, float]

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Law:
    """A law: its reference module, its twin, and their functions in pairs (``Class.method`` for a
    method of the reference)."""

    name: str
    reference: str
    twin: str
    pairs: tuple[tuple[str, str], ...]


LAWS = (
    Law(
        "variable admittance",
        "langenv.control.admittance",
        "langenv.control.admittance_kernels",
        (("VariableAdmittance.step", "step"),),
    ),
    Law(
        "the pace laws, the aligner and its audio command, the action map",
        "langenv.control.pacing",
        "langenv.control.pacing_kernels",
        (
            ("optimal_paces", "optimal_paces"),
            ("audio_command", "audio_command"),
            ("misalignment_feedback", "misalignment_feedback"),
            ("aligner_commands", "aligner_commands"),
            ("command_from_action", "command_from_action"),
            ("action_from_command", "action_from_command"),
            ("PaceActuator.step", "step"),
        ),
    ),
    Law(
        "the phrase choice",
        "langenv.speech.choice",
        "langenv.speech.choice_kernels",
        (("nearest", "nearest"),),
    ),
    Law(
        "the motion ETC t_x",
        "langenv.control.motion_etc",
        "langenv.control.motion_etc_kernels",
        (
            ("estimate_parts", "estimate_parts"),
            ("finish_parts", "finish_parts"),
            ("finish", "finish"),
            ("to_switch", "to_switch"),
            ("ramp_end", "ramp_end"),
            ("table2", "table2"),
            ("nominal_rest", "nominal_rest"),
        ),
    ),
    Law(
        "the speech ETC t_a and the pause rule",
        "langenv.speech.graph",
        "langenv.speech.graph_kernels",
        (("PhraseGraph.eta", "eta"), ("PhraseGraph.pause_length", "fill")),
    ),
    Law(
        "the reward",
        "langenv.task.reward",
        "langenv.task.reward_kernels",
        (("integrands", "integrands"), ("step_terms", "step_terms"), ("total", "total")),
    ),
)


@pytest.mark.parametrize("law", LAWS, ids=[law.name for law in LAWS])
def test_every_twin_sits_beside_its_reference_named_alike(law: Law) -> None:
    package, name = law.reference.rsplit(".", 1)
    assert law.twin == f"{package}.{name}_kernels", law.twin
    ref, twin = importlib.import_module(law.reference), importlib.import_module(law.twin)
    assert Path(ref.__file__ or "").parent == Path(twin.__file__ or "").parent
    for ours, theirs in law.pairs:
        assert callable(reduce(getattr, ours.split("."), ref)), ours
        assert theirs in twin.__all__ and callable(getattr(twin, theirs)), theirs


# ------------------------------------------------------------------ the twins agree
def same(got: Any, want: Any) -> bool:
    """The same floats to the bit (-0.0 is not 0.0), NaN for NaN."""
    g, w = np.atleast_1d(np.asarray(got, float)), np.atleast_1d(np.asarray(want, float))
    return g.shape == w.shape and all(
        (math.isnan(a) and math.isnan(b)) or struct.pack("<d", a) == struct.pack("<d", b)
        for a, b in zip(g.tolist(), w.tolist(), strict=True)
    )


finite = st.floats(-5.0, 5.0)
times = st.floats(0.0, 60.0)
fraction = st.floats(0.0, 1.0)


@settings(max_examples=200, deadline=None)
@given(
    st.tuples(finite, finite, finite),
    st.tuples(st.floats(-50.0, 50.0), st.floats(-50.0, 50.0), st.floats(-50.0, 50.0)),
    st.floats(0.5, 1.5),
    st.floats(-5.0, 5.0),
    st.floats(1.0, 40.0),
    st.floats(10.0, 200.0),
)
def test_admittance(
    v: tuple[float, ...], f: tuple[float, ...], p: float, p_dot: float, m: float, d: float
) -> None:
    law = VariableAdmittance(AdmittanceParams(mass=m, damping=d))
    want = law.step(np.array(v), np.array(f), p, p_dot, 0.002).tolist()
    s = law.settings()
    got = admittance_k.step(*v, *f, p, p_dot, 0.002, s["d_over_m"], s["inv_d"])
    assert same(got, (admittance_k.OK, *want))


@settings(max_examples=300, deadline=None)
@given(times, times, fraction, st.floats(0.1, 20.0), st.floats(0.1, 20.0))
def test_aligner(t_x: float, t_a: float, c: float, k_c: float, k_a: float) -> None:
    gains = pacing.AlignerGains(k_a=k_a, k_c=k_c)
    p_star, a_star = pacing.optimal_paces(t_x, t_a)
    assert same(pacing_k.optimal_paces(t_x, t_a), (p_star, a_star))
    k_ca = k_c / k_a
    assert same(pacing_k.audio_command(a_star, c, k_ca), pacing.audio_command(a_star, c, gains))
    for k_em, clip, on in ((0.0, 0.5, True), (1.0, 0.5, True), (2.5, 0.2, False)):
        assert same(
            pacing_k.misalignment_feedback(t_x, t_a, k_em, clip),
            pacing.misalignment_feedback(t_x, t_a, k_em, clip),
        )
        assert same(
            pacing_k.aligner_commands(t_x, t_a, c, k_ca, k_em, clip, on),
            pacing.aligner_commands(t_x, t_a, c, gains, k_em, clip, on),
        )


@settings(max_examples=300, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(-4.0, 4.0), st.floats(1.01, 2.0))
def test_action_map(u: float, cmd: float, upper: float) -> None:
    c_min = pacing.COMMAND_MIN
    assert same(pacing_k.command_from_action(u, upper, c_min), pacing.command_from_action(u, upper))
    want = pacing.action_from_command(cmd, upper)
    assert same(pacing_k.action_from_command(cmd, upper, c_min), want)
    assert same(pacing_k.action(cmd, upper, c_min), float(np.float32(want)))


@settings(max_examples=200, deadline=None)
@given(st.floats(0.6, 1.4), st.floats(0.6, 1.4), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0))
def test_pace_actuator(p: float, a: float, p_cmd: float, a_cmd: float) -> None:
    lim = pacing.PaceLimits()
    plant = pacing.PaceActuator(lim)
    plant.p, plant.a = p, a
    plant.step(p_cmd, a_cmd, 0.002)
    got = pacing_k.step(p, a, p_cmd, a_cmd, 0.002, lim.k_p, lim.k_a, lim.p_min, lim.p_max,
                        lim.a_min, lim.a_max)  # fmt: skip
    assert same(got, (plant.p, plant.p_dot, plant.a))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from([0.5, 1.0, 2.0, 2.5, 3.0, 7.25]), min_size=1, max_size=6),
       st.floats(-10.0, 20.0) | st.just(math.nan))  # fmt: skip
def test_phrase_choice(mids: list[float], x: float) -> None:
    """The first of the nearest, ties included (several children of one middle length)."""
    kids = [f"v{i}" for i in range(len(mids))]
    want = choice.nearest(kids, dict(zip(kids, mids, strict=True)), x)
    index = np.arange(len(mids) + 2, dtype=np.int64)[1:-1]  # kids[lo:hi] of a longer array
    got = choice_k.nearest(0, len(mids), index, np.array([0.0, *mids]), x)
    assert f"v{got - 1}" == want


@settings(max_examples=200, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(0.1, 8.0))
def test_phrase_choice_action_is_the_inverse_of_the_target(u: float, ratio: float) -> None:
    assert choice.choice_action(choice.duration_factor(u)) == pytest.approx(u, abs=1e-12)
    assert choice.duration_factor(choice.choice_action(ratio)) == pytest.approx(
        min(4.0, max(0.25, ratio)), rel=1e-12
    )


@settings(max_examples=60, deadline=None)
@given(pause_dags(), st.floats(0.0, 1.0), st.floats(0.0, 30.0))
def test_speech_eta_and_pause_rule(g: PhraseGraph, frac: float, t_x: float) -> None:
    for i, u in enumerate(g.phrases):
        remaining = frac * g.slot(u)
        assert same(c_eta(g, i, remaining, t_x), g.eta(u, remaining, t_x))
        if u in g.pauses:
            assert same(c_fill(g, i, t_x), g.pause_length(u, t_x))


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 60.0), st.floats(0.6, 1.4), st.floats(0.0, 60.0), st.floats(0.6, 1.4),
       st.booleans(), st.booleans(), st.floats(0.0, 5.0), st.floats(0.0, 5.0))  # fmt: skip
def test_reward(
    t_a: float, a: float, t_x: float, p: float, m_on: bool, s_on: bool, w_em: float, w_p: float
) -> None:
    em, pace = reward.integrands(t_a, a, t_x, p, m_on, s_on)
    assert same(reward_k.integrands(mjc.pow_address(), t_a, a, t_x, p, m_on, s_on), (em, pace))
    terms = reward.step_terms(em, pace, w_em, w_p)
    assert same(reward_k.step_terms(em, pace, w_em, w_p, T_SCALE), terms)
    assert same(reward_k.total(*terms, -w_em), reward.total(*terms, -w_em))


@pytest.fixture(scope="module")
def fast() -> motion_etc.FastETC:
    params = AdmittanceParams()
    return motion_etc.FastETC(Guide(default_exercise(), params), VariableAdmittance(params))


speed = st.floats(-0.3, 0.5)


@settings(max_examples=200, deadline=None)
@given(
    st.integers(0, 10),
    st.floats(0.0, 1.0),
    st.booleans(),
    st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.05, 0.05)),
    st.tuples(speed, speed, speed),
    st.tuples(speed, speed, speed),
)
def test_motion_etc_estimate(
    fast: motion_etc.FastETC,
    leg: int,
    where: float,
    done: bool,
    dx: Vec3,
    v: Vec3,
    c: Vec3,
) -> None:
    """The query (the projection, the behind-the-start tables, the closed form to the switch,
    the rest table) from states near the path, behind a leg's start and past its end too."""
    traj = fast.guide.trajectory
    ends = [0.0, *(float(s) for s in traj.waypoint_s)]
    leg = leg % (len(ends) - 1)
    s = ends[leg] + (ends[leg + 1] - ends[leg]) * (1.2 * where - 0.1)
    s = min(max(s, 0.0), traj.length)
    seg, t = traj.locate(s)
    xd = seg.frame(t)[0]
    x = (xd[0] + dx[0], xd[1] + dx[1], xd[2] + dx[2])
    args: tuple[Any, ...] = (leg, s, done, x, v, c)
    want = motion_etc.estimate_parts(fast.prm, fast.tab, traj, *args)
    assert same(motion_etc_k.estimate_parts(fast.prm, fast.tab, fast.path, *args), want)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 10), st.floats(-0.05, 0.6), speed, speed, st.floats(-0.2, 0.4))
def test_motion_etc_finish(
    fast: motion_etc.FastETC, leg: int, q: float, u: float, w: float, dist: float
) -> None:
    prm, tab = fast.prm, fast.tab
    leg %= int(prm[motion_etc_k.ETC_PARAMS.at.n_legs])
    assert same(
        motion_etc_k.finish(prm, tab, leg, q, u, w), motion_etc.finish(prm, tab, leg, q, u, w)
    )
    assert same(
        motion_etc_k.finish_parts(prm, tab, leg, q, u, w),
        motion_etc.finish_parts(prm, tab, leg, q, u, w),
    )
    assert same(motion_etc_k.to_switch(prm, dist, u, w), motion_etc.to_switch(prm, dist, u, w))
    assert same(motion_etc_k.ramp_end(prm, u, w), motion_etc.ramp_end(prm, u, w))
    assert same(motion_etc_k.nominal_rest(prm, tab, leg), motion_etc.nominal_rest(prm, tab, leg))
    nu = int(prm[motion_etc_k.ETC_PARAMS.at.rest_n])
    off = int(prm[motion_etc_k.ETC_PARAMS.at.rest_offset]) + leg * nu * nu
    u0, du = prm[motion_etc_k.ETC_PARAMS.at.rest_u0], prm[motion_etc_k.ETC_PARAMS.at.rest_du]
    assert same(
        motion_etc_k.table2(tab, off, u0, du, nu, u, w),
        motion_etc.table2(tab, off, float(u0), float(du), nu, u, w),
    )


# ------------------------------------------------------------------ constants written once
#: The constants the laws share, each assigned in one file (a copy under another name, ``_X`` or
#: ``_LC_X``, counts as an assignment).
CONSTANTS = (
    "CHOICE_OCTAVES",  # the target-duration action's octaves per unit
    "RATE_TAU",  # the terminal phase's rate estimate's time constant
    "RATE_FLOOR",  # its lowest rate
    "NEW_HORIZON",  # a rise of t_x that starts a new leg's horizon
    "COMMAND_MIN",  # the pace command at u = -1
    "RATE_AVG_TAU",  # the learned aligner's features
    "LOST_SCALE",
    "FINE_SCALE",
    "PRIOR_SCALE",
)
_PACKAGES = ("langenv", "policies", "train", "eval", "bench", "langctrl")
#: A number assigned with a comment naming where it was copied from (``X = 0.04  # a.b.X``).
_COPY = re.compile(r"^\s*\w+\s*(?::[^=]*)?=\s*[-+\d.e]+\s*#\s*[\w.]+\.[A-Z_]+\b")


def _sources() -> dict[str, list[str]]:
    return {
        path.relative_to(ROOT).as_posix(): path.read_text().splitlines()
        for package in _PACKAGES
        for path in sorted((ROOT / package).rglob("*.py"))
    }


def test_each_shared_constant_is_assigned_in_one_file() -> None:
    sources = _sources()
    for name in CONSTANTS:
        assign = re.compile(rf"^\s*(?:_\w*?)?{name}\s*(?::[^=]*)?=(?!=)")
        files = sorted(f for f, lines in sources.items() if any(map(assign.match, lines)))
        assert len(files) == 1, f"{name} assigned in {files}"


def test_no_constant_is_a_copy_by_value() -> None:
    copies = [
        f"{f}:{i + 1}: {line.strip()}"
        for f, lines in _sources().items()
        for i, line in enumerate(lines)
        if _COPY.match(line)
    ]
    assert copies == [], copies
