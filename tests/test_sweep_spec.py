"""Sweep files: every problem named (file, key, line) before anything starts."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from eval.sweep import SweepError, load_spec
from eval.sweep.spec import _key_lines
from langenv.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    return path


def _error(tmp_path: Path, text: str) -> SweepError:
    with pytest.raises(SweepError) as info:
        load_spec(_write(tmp_path, text))
    assert isinstance(info.value, ConfigError)
    assert str(tmp_path / "sweep.yaml") in str(info.value)
    return info.value


USERS = "users: {synthetic: 2}\n"


@pytest.mark.parametrize(
    ("grid", "key", "words"),
    [
        ("  policy: [lc]\n  lc.k_zz: [1.0]\n", "grid.lc.k_zz", "unknown parameter"),
        ("  policy: [lc]\n  env.bogus: [1.0]\n", "grid.env.bogus", "unknown env parameter"),
        ("  policy: [lc]\n  ac.k_c: [1.0]\n", "grid.ac.k_c", "unknown parameter"),
        ("  policy: [ac]\n  ac.k_c: [1.0]\n", "grid.ac.k_c", "unknown parameter"),
        ("  policy: [lc]\n  speed: [1.0]\n", "grid.speed", "unknown parameter"),
        ("  policy: [lc]\n  lc.k_a: [1.0]\n", "grid.lc.k_a", "ambiguous"),
        ("  policy: [lc]\n  lc.k_c: {linspace: [5, 1, 3]}\n", "grid.lc.k_c", "bad range"),
        ("  policy: [lc]\n  lc.k_c: {logspace: [0, 1, 3]}\n", "grid.lc.k_c", "bad range"),
        ("  policy: [lc]\n  lc.k_c: {range: [0, 1, -1]}\n", "grid.lc.k_c", "bad range"),
        ("  policy: [lc]\n  lc.k_c: [-1.0]\n", "grid.lc.k_c", "bad range"),
        ("  policy: [lc]\n  env.admittance.damping: [0.0]\n", "grid.env.admittance.damping", "bad"),
        ("  policy: [lc]\n  exercise: [moonwalk]\n", "grid.exercise", "unknown exercise"),
        ("  policy: [lc, zz]\n", "grid.policy", "unknown policy 'zz'"),
        ("  policy: [ppo:nowhere.zip]\n", "grid.policy", "unknown policy"),
        ("  policy: []\n", "grid.policy", "empty grid"),
        ("  policy: [lc]\n  lc.k_c: []\n", "grid.lc.k_c", "empty grid"),
        ("  policy: [lc]\n  decision_hz: [7]\n", "grid.decision_hz", "dividing 500"),
        ("  policy: [lc]\n  phrase_graph: [nowhere.yaml]\n", "grid.phrase_graph", "phrase graph"),
    ],
)
def test_named_errors(tmp_path: Path, grid: str, key: str, words: str) -> None:
    err = _error(tmp_path, "grid:\n" + grid + USERS)
    assert err.key.startswith(key), err
    assert words in err.detail, err


def test_every_problem_at_once_with_lines(tmp_path: Path) -> None:
    text = "grid:\n  policy: [lc]\n  lc.k_zz: [1.0]\n  lc.k_c: {linspace: [2, 1, 3]}\n"
    text += "users: {}\nfoo: 1\n"
    err = _error(tmp_path, text)
    keys = [k for k, _ in err.problems]
    assert keys[0] == "foo (line 6)"
    assert "grid.lc.k_zz (line 3)" in keys
    assert "grid.lc.k_c (line 4)" in keys
    assert any(k.startswith("users") for k in keys)
    assert len(str(err).splitlines()) == len(err.problems)


@pytest.mark.parametrize(
    ("text", "key", "words"),
    [
        ("", "", "mapping"),
        ("grid: {policy: [lc]}\n", "users", "user set"),
        ("grid: {}\n" + USERS, "grid", "empty grid"),
        ("grid: {policy: [lc]}\nusers: {synthetic: 0}\n", "users.synthetic", "empty grid"),
        ("grid: {policy: [lc]}\nusers: {sessions: nowhere}\n", "users.sessions", "not a directory"),
        ("grid: {policy: [lc]}\nusers: {synthetic: 1, sessions: x}\n", "users", "exactly one"),
        ("grid: {policy: [lc]}\nbatch_size: 0\n" + USERS, "batch_size", ">= 1"),
        (
            "grid: {policy: [lc], lc.k_c: [1.0]}\n"
            "sample: {n: 2, space: {lc.k_c: {uniform: [0, 1]}}}\n" + USERS,
            "sample.space.lc.k_c",
            "not both",
        ),
        (
            "grid: {policy: [lc]}\nsample: {n: 2, space: {lc.k_em: {uniform: [1, 0]}}}\n" + USERS,
            "sample.space.lc.k_em",
            "bad range",
        ),
        (
            "grid: {policy: [lc]}\n"
            "sample: {n: 2, space: {lc.k_em: {loguniform: [0, 1]}}}\n" + USERS,
            "sample.space.lc.k_em",
            "bad range",
        ),
        ("grid: {policy: [lc]}\nsample: {n: 0, space: {}}\n" + USERS, "sample.n", ">= 1"),
    ],
)
def test_named_errors_outside_the_grid(tmp_path: Path, text: str, key: str, words: str) -> None:
    err = _error(tmp_path, text)
    assert err.key.startswith(key), err
    assert words in str(err), err


def test_a_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(SweepError, match="cannot read"):
        load_spec(tmp_path / "nope.yaml")


def test_key_lines() -> None:
    assert _key_lines("a: 1\nb:\n  c: 2\n") == {"a": 1, "b": 2, "b.c": 3}


def test_bad_file_starts_nothing(tmp_path: Path) -> None:
    """The command exits 1 naming the problem, and writes nothing (no output directory)."""
    spec = _write(tmp_path, "grid:\n  policy: [lc]\n  lc.k_zz: [1.0]\n" + USERS)
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "langctrl", "sweep", str(spec), "--out", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 1, proc.stderr
    assert "grid.lc.k_zz (line 3): unknown parameter" in proc.stderr
    assert not out.exists()


def test_the_example_loads() -> None:
    spec = load_spec(ROOT / "configs" / "sweeps" / "example.yaml")
    assert spec.param_names == ("lc.k_c", "env.admittance.damping")


def test_a_model_that_cannot_speak_a_graph_of_the_grid_is_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Checked with the model's own rule (PPOPolicy.use_graph) before any worker starts: here a
    model refuses every graph of more than 6 choices, as a 'scores' model of 6 outputs does."""
    from langenv.errors import GraphChoicesError
    from policies.learned import PPOPolicy

    def refuse(self: PPOPolicy, spoken: object) -> None:
        choices = getattr(spoken, "max_children", 0)
        if choices > 6:
            raise GraphChoicesError(self.path, getattr(spoken, "label", "?"), 6, choices)

    monkeypatch.setattr(PPOPolicy, "use_graph", refuse)
    model = ROOT / "models" / "ppo_aligner.zip"
    grid = f"  policy: [lc, 'ppo:{model}']\n  phrase_graph: [study, default]\n"
    err = _error(tmp_path, "grid:\n" + grid + USERS)
    assert err.key.startswith("grid.policy")
    assert "default" in err.detail and "9 choices" in err.detail and "study" not in err.detail
    load_spec(
        _write(tmp_path, f"grid:\n  policy: ['ppo:{model}']\n  phrase_graph: [study]\n{USERS}")
    )
