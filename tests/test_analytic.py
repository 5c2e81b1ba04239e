"""The analytic controllers as policies (policies/analytic.py): names, checks, EM feedback."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.env import T_SCALE
from langenv.errors import ConfigError
from langenv.pacing import command_from_action
from policies.analytic import (
    AdmittanceController,
    LanguageController,
    make_analytic,
)


def _obs(t_x: float, t_a: float, coop: float = 1.0, motion_done: bool = False) -> np.ndarray:
    obs = np.zeros(19, np.float32)
    obs[0], obs[1], obs[5] = t_x / T_SCALE, t_a / T_SCALE, 2.0 * coop - 1.0
    obs[13] = 1.0 if motion_done else -1.0
    return obs


def test_names_build_the_right_controllers() -> None:
    assert isinstance(make_analytic("ac"), AdmittanceController)
    lc, noap, em = make_analytic("lc"), make_analytic("lc-noap"), make_analytic("lc-em")
    assert (lc.name, lc.phrase_graph, lc.decision_hz, lc.k_em) == ("lc", "lc", 500, 0.0)
    assert (noap.name, noap.phrase_graph) == ("lc-noap", "lc-noap")
    assert (em.name, em.phrase_graph, em.k_em) == ("lc-em", "lc", 1.0)
    assert make_analytic("lc", decision_hz=25).decision_hz == 25
    with pytest.raises(KeyError, match="lc-em"):
        make_analytic("lq")


@pytest.mark.parametrize("field", ["k_em", "em_clip"])
@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_bad_feedback_parameters_raise(field: str, bad: float) -> None:
    with pytest.raises(ConfigError, match=field):
        LanguageController(**{field: bad})  # type: ignore[arg-type]


@settings(max_examples=60, deadline=None)
@given(
    t_x=st.floats(0.5, 30.0),
    t_a=st.floats(0.5, 30.0),
    coop=st.floats(0.0, 1.0),
    k=st.floats(0.0, 5.0),
)
def test_em_feedback_shifts_only_the_physical_pace(
    t_x: float, t_a: float, coop: float, k: float
) -> None:
    """``p_cmd = p* - clip(k EM, ±em_clip)`` while moving; the audio command is LC's."""
    lc, em = LanguageController(), LanguageController(k_em=k, em_clip=0.5)
    base, act = lc.act(_obs(t_x, t_a, coop)), em.act(_obs(t_x, t_a, coop))
    shift = float(np.clip(k * (t_a - t_x), -0.5, 0.5))
    p0, p1 = command_from_action(float(base[0]), 1.4), command_from_action(float(act[0]), 1.4)
    # the action map saturates at u = ±1 (p_cmd in [-1.5, 1.4])
    assert p1 == pytest.approx(float(np.clip(p0 - shift, -1.5, 1.4)), abs=1e-5)
    assert act[1] == base[1] and act[2] == base[2] == 0.0


def test_em_feedback_is_off_once_the_motion_is_over() -> None:
    lc, em = LanguageController(), LanguageController(k_em=2.0)
    obs = _obs(0.0, 3.0, motion_done=True)
    assert np.array_equal(lc.act(obs), em.act(obs))
