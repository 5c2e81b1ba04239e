"""The aligner's optimal paces (SPEC §1): constraint, optimality and the paper's swapped typo."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from langenv.control.pacing import AlignerGains, audio_command, optimal_paces
from langenv.errors import ConfigError

etc = st.floats(min_value=0.05, max_value=60.0, allow_nan=False)


@given(t_x=etc, t_a=etc)
def test_optimal_paces_satisfy_alignment(t_x: float, t_a: float) -> None:
    p, a = optimal_paces(t_x, t_a)
    assert math.isclose(t_x / p, t_a / a, rel_tol=1e-9)


@given(t_x=etc, t_a=etc)
def test_optimal_paces_minimise_distance_to_natural(t_x: float, t_a: float) -> None:
    p, a = optimal_paces(t_x, t_a)
    best = (p - 1.0) ** 2 + (a - 1.0) ** 2
    s = t_x / t_a
    # every feasible pair (p, a = p / s) on a dense grid is no better
    grid = np.linspace(1e-3, 3.0, 4001)
    cost = (grid - 1.0) ** 2 + (grid / s - 1.0) ** 2
    assert best <= cost.min() + 1e-9


def test_paper_formula_is_swapped() -> None:
    # motion longer than speech (s > 1): motion must speed up (p* > a*), speech slow down.
    p, a = optimal_paces(12.0, 8.0)
    assert p > 1.0 > a
    s = 12.0 / 8.0
    paper_p, paper_a = (s + 1) / (s * s + 1), (s * s + s) / (s * s + 1)
    assert not math.isclose(12.0 / paper_p, 8.0 / paper_a)  # the printed formula misaligns
    assert math.isclose(12.0 / p, 8.0 / a)


def test_speech_over_returns_natural_paces() -> None:
    assert optimal_paces(5.0, 0.0) == (1.0, 1.0)


@pytest.mark.parametrize("bad", [-1.0, math.nan, math.inf])
def test_bad_etc_raises(bad: float) -> None:
    with pytest.raises(ConfigError, match="t_x"):
        optimal_paces(bad, 1.0)
    with pytest.raises(ConfigError, match="t_a"):
        optimal_paces(1.0, bad)


@given(a_star=st.floats(0.0, 1.3), c=st.floats(0.0, 1.0), a=st.floats(0.6, 1.4))
def test_audio_command_reproduces_the_pace_law(a_star: float, c: float, a: float) -> None:
    g = AlignerGains()
    cmd = audio_command(a_star, c, g)
    assert math.isclose(g.k_a * (cmd - a), g.k_a * (a_star - a) - g.k_c * (1.0 - c), abs_tol=1e-9)


def test_gains_validated() -> None:
    with pytest.raises(ConfigError, match="k_p"):
        AlignerGains(k_p=0.0)
    with pytest.raises(ConfigError, match="k_c"):
        AlignerGains(k_c=-1.0)
