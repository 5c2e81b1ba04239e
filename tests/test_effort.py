"""The mean path error and the person's effort: traces kept in the episode log, the two session
metrics (eval.metrics), and both in sessions.csv whichever way an episode was run."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from eval.episode import EpisodeLog, EpisodeRecorder
from eval.metrics import episode_metrics
from eval.report import read_sessions_csv
from langctrl.jobs.compare import main
from langenv.errors import ConfigError
from tests.test_metrics import hand_log


def test_path_error_and_effort_are_time_means_over_the_motion() -> None:
    dev = np.array([0.001, 0.002, 0.004, 0.004, 0.002, 0.001, 9, 9, 9, 9])  # 9: after motion
    force = np.zeros((10, 3))
    force[:, 0] = [0, 3, 4, 0, 0, 0, 50, 50, 50, 50]
    force[:, 1] = [0, 4, 3, 6, 0, 0, 0, 0, 0, 0]  # |F| = 0, 5, 5, 6, 0, 0 while moving
    m = episode_metrics(hand_log(path_deviation=dev, f_user=force))
    assert m["path_error"] == pytest.approx(np.mean(dev[:6]))
    assert m["effort"] == pytest.approx(16.0 / 6.0)


def test_without_the_traces_both_are_nan() -> None:
    m = episode_metrics(hand_log())
    assert math.isnan(float(m["path_error"])) and math.isnan(float(m["effort"]))


@pytest.mark.parametrize(
    "value", [np.full(9, 0.001), np.full(10, -0.001), np.full(10, np.nan), "far"]
)
def test_log_refuses_a_bad_deviation_trace(value: object) -> None:
    with pytest.raises(ConfigError, match="path_deviation"):
        hand_log(path_deviation=value)


def test_npz_keeps_the_deviation(tmp_path: Path) -> None:
    dev = np.linspace(0.0, 0.01, 10)
    back = EpisodeLog.load_npz(hand_log(path_deviation=dev).save_npz(tmp_path / "x.npz"))
    assert back.path_deviation is not None
    assert np.array_equal(back.path_deviation, dev)
    older = EpisodeLog.load_npz(hand_log().save_npz(tmp_path / "y.npz"))
    assert older.path_deviation is None


def _info(t: float, dev: float | None) -> dict[str, object]:
    info: dict[str, object] = dict(
        time=t, cooperation=1.0, hand_speed=0.1, p=1.0, a=1.0, t_x=2.0 - t, t_a=2.0 - t,
        em=0.0, motion_done=t >= 2.0, speech_done=t >= 2.0,
    )  # fmt: skip
    if dev is not None:
        info["path_deviation"] = dev
    return info


def test_recorder_records_the_deviation_by_step_and_by_block() -> None:
    rec = EpisodeRecorder(policy="lc", user="u")
    rec.append(_info(0.0, 0.001))
    block = {k: np.array([v, v]) for k, v in _info(1.0, 0.002).items()}
    block["time"] = np.array([1.0, 2.0])
    rec.extend(block, "intro")
    log = rec.build(0.0, t_motion=2.0, t_speech=2.0)
    assert log.path_deviation is not None
    assert log.path_deviation.tolist() == [0.001, 0.002, 0.002]
    rec = EpisodeRecorder(policy="lc", user="u")
    rec.append(_info(0.0, 0.001))
    rec.append(_info(1.0, None))
    with pytest.raises(ConfigError, match="'path_deviation' in 1 of 2"):
        rec.build(0.0, t_motion=2.0, t_speech=2.0)


def test_sessions_csv_has_both_for_compiled_and_stepped_episodes(tmp_path: Path) -> None:
    """LC runs as a compiled pace law (``run_law``: the deviation comes from the kernels' rows),
    lc-fill-end a Python step per tick: both give the two columns."""
    out = tmp_path / "out"
    args = ["--policies", "lc,lc-fill-end", "--users", "synthetic:1", "--out", str(out)]
    assert main([*args, "--workers", "1", "--no-audio", "--no-figures"]) == 0
    rows = read_sessions_csv(out / "sessions.csv")
    assert [r["policy"] for r in rows] == ["lc", "lc-fill-end"]
    for r in rows:
        assert 0.0 < float(r["path_error"]) < 0.02, r["policy"]  # m: the hand stays on the path
        assert 0.0 <= float(r["effort"]) < 40.0, r["policy"]  # N
