"""Fidelity (eval.fidelity) and the behaviour it pins: the plant against the study's recordings."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import langenv  # noqa: F401  (registers LangCtrl-v0)
from eval.fidelity import (
    COOP_BINS,
    FidelityTargets,
    Trace,
    controller_of,
    measure,
    run_checks,
    speed_by_cooperation,
    trace_from_session,
)
from langctrl.jobs.fidelity import main
from langenv.control.admittance import AdmittanceParams
from langenv.users import Session

SESSIONS = Path(__file__).parents[2] / "shared" / "sessions"
P = AdmittanceParams()


def _trace(name: str, c: float, v: float, n: int = 200, p: float = 1.0) -> Trace:
    return Trace(
        name=name,
        controller=str(controller_of(name)),
        length=n / 50.0,
        cooperation=np.full(n, c),
        speed=np.full(n, v),
        p=np.full(n, p),
        a=np.full(n, 0.9),
        em=np.zeros(n),
        speech_at_start=13.0,
        am=0.5,
    )


def test_controller_of_the_file_suffix() -> None:
    assert controller_of("u3_lcnoap") == "lc-noap"
    assert controller_of("u3_lc") == "lc"
    assert controller_of("u3_AC") == "ac"
    assert controller_of("lab_session") is None


def test_speed_by_cooperation_bins() -> None:
    med, secs = speed_by_cooperation([_trace("a_ac", 0.97, 0.11), _trace("b_ac", 0.65, 0.05)])
    assert len(med) == len(COOP_BINS) - 1
    assert med[-1] == pytest.approx(0.11) and secs[-1] == pytest.approx(4.0)
    assert med[1] == pytest.approx(0.05) and np.isnan(med[0])


def test_checks_pass_and_fail_on_the_targets() -> None:
    rec = measure([_trace("u1_ac", 0.97, 0.11), _trace("u1_lc", 0.9, 0.1, p=0.95)])
    same = measure([_trace("u1_ac", 0.97, 0.11), _trace("u1_lc", 0.9, 0.1, p=0.95)])
    assert all(c.passed for c in run_checks(rec, same, FidelityTargets()))
    slow = measure([_trace("u1_ac", 0.97, 0.05, n=400), _trace("u1_lc", 0.9, 0.1, p=0.7)])
    failed = {c.name for c in run_checks(rec, slow, FidelityTargets()) if not c.passed}
    assert "length ratio ac" in failed
    assert "median p lc" in failed
    assert any(name.startswith("AC speed") for name in failed)


def test_trace_of_a_recording() -> None:
    t = np.arange(0.55, 10.0, 0.02)
    s = Session(
        "u9_ac",
        t,
        np.full(t.size, 0.9),
        ee_speed=np.full(t.size, 0.1),
        t_a=np.r_[3.3, np.full(t.size - 1, 13.4)],
    )
    tr = trace_from_session(s, "ac")
    assert tr.length == pytest.approx(t[-1])
    assert tr.speech_at_start == pytest.approx(13.4)  # the first-sample glitch is skipped
    with pytest.raises(ValueError, match="ee_speed"):
        trace_from_session(Session("u9_ac", t, np.full(t.size, 0.9)), "ac")


def _ac_session(force: float) -> dict[str, float]:
    env = gym.make(
        "LangCtrl-v0",
        users=lambda t, v, b: force * np.asarray(b),
        phrase_graph="ac",
        max_episode_steps=1500,
    )
    env.reset(seed=0)
    traj = env.unwrapped.motion.trajectory  # type: ignore[attr-defined]
    lo, hi = traj.waypoint_s[0] / traj.length, traj.waypoint_s[1] / traj.length
    middle = (lo + 0.3 * (hi - lo), lo + 0.7 * (hi - lo))  # the middle of the line back
    speeds, done = [], False
    info: dict[str, float] = {}
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(3, np.float32))
        done = terminated or truncated
        if middle[0] < info["progress"] < middle[1] and not info["motion_done"]:
            speeds.append(info["hand_speed"])
    return {"t_motion": info["t_motion"], "truncated": truncated, "plateau": np.median(speeds)}


def test_hand_speed_under_a_steady_resistance() -> None:
    """Against a steady push the hand settles at (F_prop - (|F| - deadband)) / D0, as recorded."""
    free = _ac_session(0.0)
    assert free["plateau"] == pytest.approx(P.plateau_speed, abs=0.003)
    pushed = _ac_session(-9.0)  # 4 N above the deadband
    assert pushed["plateau"] == pytest.approx((P.propel_force - 4.0) / P.damping, abs=0.003)
    assert pushed["t_motion"] > free["t_motion"] + 2.0


@pytest.mark.slow
@pytest.mark.parametrize("force", [10.0, 15.0, 20.0])
def test_a_helping_user_finishes_sooner(force: float) -> None:
    free = _ac_session(0.0)
    helped = _ac_session(force)
    assert not helped["truncated"]
    assert helped["t_motion"] < free["t_motion"] - 0.2


@pytest.mark.slow
def test_fidelity_cli_on_one_user(tmp_path: Path) -> None:
    if not SESSIONS.is_dir():
        pytest.skip(f"recorded sessions not found at {SESSIONS}")
    data = tmp_path / "sessions"
    data.mkdir()
    for stem in ("u2_ac", "u2_lcnoap", "u2_lc"):
        shutil.copy(SESSIONS / f"{stem}.csv", data)
    out = tmp_path / "out"
    assert main(["--sessions", str(data), "--out", str(out), "--workers", "1"]) == 0
    report = json.loads((out / "fidelity.json").read_text())
    assert (out / "fidelity.png").stat().st_size > 10_000
    assert "| u2_lc | lc |" in (out / "fidelity.md").read_text()
    lengths = report["simulated"]["length"]
    recorded = report["recorded"]["length"]
    for ctrl in ("ac", "lc-noap", "lc"):
        (name,) = lengths[ctrl]
        # this cooperative user's sessions are reproduced to within 10 %
        assert lengths[ctrl][name] / recorded[ctrl][name] == pytest.approx(1.0, abs=0.1)
    names = {c["name"] for c in report["checks"]}
    assert {"length ratio ac", "speech at start lc", "median AM lc-noap"} <= names


def test_fidelity_cli_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--sessions", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "no session files match" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:  # the parser's own check
        main(["--sessions", str(tmp_path), "--users", "synthetic:x"])
    assert info.value.code == 2
    assert "--users" in capsys.readouterr().err
