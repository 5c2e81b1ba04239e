"""The compiled tick (langenv.kernels) against the Python parts, the reference: bit-identical."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from langenv.control.admittance import AdmittanceParams
from langenv.control.cooperation import CooperationFilter
from langenv.control.trajectory import default_exercise
from langenv.errors import ActionError, ConfigError
from langenv.motion.tick import GuidedArm
from langenv.robot.arm import Arm
from langenv.robot.force_sensor import ForceSensor
from langenv.robot.safety import SafetyLimits

pytestmark = pytest.mark.portable


def _pair(**arm_kwargs: float) -> tuple[GuidedArm, GuidedArm]:
    def make(compiled: bool) -> GuidedArm:
        return GuidedArm(
            Arm(**arm_kwargs),  # type: ignore[arg-type]
            default_exercise(),
            AdmittanceParams(),
            ForceSensor(),
            CooperationFilter(),
            SafetyLimits(),
            compiled=compiled,
        )

    fast, ref = make(True), make(False)
    assert fast.compiled and not ref.compiled
    return fast, ref


def _snapshot(m: GuidedArm) -> tuple[object, ...]:
    st = m.state
    vectors = np.concatenate(
        [
            m.v_ref,
            m.v_cmd,
            m.f_measured,
            m.hand_velocity,
            m.tangent(),
            m.arm.data.qpos,
            m.arm.data.qvel,
            m.arm.reference_position,
        ]
    )
    scalars = (st.s, st.leg, st.done, m.t_x, m.time, m.t_motion_end, m.path_deviation)
    return (*scalars, m.hand_speed, m.cooperation, m.progress, repr(m.safety_stop), vectors)


def _same(a: tuple[object, ...], b: tuple[object, ...]) -> bool:
    return a[:-1] == b[:-1] and np.array_equal(a[-1], b[-1])  # type: ignore[arg-type]


def _run(fast: GuidedArm, ref: GuidedArm, force: object, pace: object, n: int, seed: int) -> None:
    """Tick both with the same inputs and noise; every observable equal after every tick."""
    fast.reset()
    ref.reset()
    rng_a, rng_b = np.random.default_rng(seed), np.random.default_rng(seed)
    assert _same(_snapshot(fast), _snapshot(ref))
    for i in range(n):
        f = force(i, fast)  # type: ignore[operator]
        p, p_dot = pace(i)  # type: ignore[operator]
        fast.tick(f, p, p_dot, rng_a)
        ref.tick(f, p, p_dot, rng_b)
        a, b = _snapshot(fast), _snapshot(ref)
        assert _same(a, b), f"tick {i}: compiled {a} != Python {b}"


def _pace(i: int) -> tuple[float, float]:
    return 1.0 + 0.3 * math.sin(i / 300), 0.5 * math.cos(i / 300)


def test_episode_with_noise_pushes_and_paces_is_bit_identical() -> None:
    fast, ref = _pair()
    gen = np.random.default_rng(7)

    def force(i: int, m: GuidedArm) -> np.ndarray:
        push = 5.0 if (i // 600) % 2 else -3.0  # along, then against the guide
        return gen.normal(0.0, 4.0, 3) + push * m.tangent()

    _run(fast, ref, force, _pace, 5000, seed=3)
    assert fast.motion_done and ref.motion_done  # braking and the end of motion covered


def test_joint_limit_avoidance_is_bit_identical() -> None:
    # margins wider than the joints' room: the re-solve (Python, from the kernel) runs every tick
    fast, ref = _pair(joint_limit_margin=4.5)
    calls = []
    avoid = fast.arm._avoid_limits

    def spy(q: np.ndarray) -> None:
        calls.append(1)
        avoid(q)

    fast.arm._avoid_limits = spy  # type: ignore[method-assign]
    _run(fast, ref, lambda i, m: np.zeros(3), lambda i: (1.0, 0.0), 400, seed=0)
    assert calls


def test_protective_stop_and_after_are_bit_identical() -> None:
    fast, ref = _pair()
    # a push far beyond the force limit after 200 ticks: a stop, then the arm holds still
    _run(fast, ref, lambda i, m: np.array([0.0, 0.0, 200.0 if i >= 200 else 0.0]), _pace, 300, 1)
    assert fast.safety_stop is not None and fast.safety_stop == ref.safety_stop
    assert fast.safety_stop.limit == "force"
    fast.reset()
    assert fast.safety_stop is None and fast.v_cmd.tolist() == [0.0, 0.0, 0.0]


def test_bad_input_raises_the_python_parts_errors() -> None:
    fast, ref = _pair()
    for m in (fast, ref):
        m.reset()
        with pytest.raises(ActionError):
            m.tick(np.array([math.nan, 0.0, 0.0]), 1.0, 0.0)
        with pytest.raises(ActionError):
            m.tick(np.zeros(4), 1.0, 0.0)
        m.reset()
        with pytest.raises(ConfigError, match="p"):
            m.tick(np.zeros(3), -1.0, 0.0)
        m.reset()
        with pytest.raises(ConfigError, match="p_dot"):
            m.tick(np.zeros(3), 1.0, math.inf)


def test_compiled_leg_law_equals_the_numpy_one() -> None:
    from langenv.control.admittance import VariableAdmittance
    from langenv.control.motion_etc import _Law

    law = _Law(VariableAdmittance(AdmittanceParams()), 0.002)
    rng = np.random.default_rng(0)
    n = 400
    q = rng.uniform(-0.05, 0.4, n)
    u, w = rng.uniform(-0.2, 0.3, n), rng.uniform(-0.2, 0.3, n)
    lateral = (rng.uniform(-0.02, 0.02, n), rng.uniform(-0.1, 0.1, n), rng.uniform(-0.1, 0.1, n))
    for lat, t_max in ((None, 60.0), (lateral, 1.5), (lateral, 0.01)):
        fast = law.simulate(q, u, w, 0.3, 0.02, lat, t_max)
        ref = law.simulate_numpy(q, u, w, 0.3, 0.02, lat, t_max)
        for a, b in zip(fast, ref, strict=True):
            assert np.array_equal(a, b)
        assert np.isinf(fast[0]).any() or t_max == 60.0


def test_cached_kernels_are_dropped_when_any_kernel_source_changes(tmp_path: Path) -> None:
    """Numba checks a cached kernel against its own file only; the package's digest covers every
    compiled module and every declaration they read."""
    from langenv.kernels import clear_stale_cache

    root = tmp_path / "pkg"
    (root / "kernels").mkdir(parents=True)
    (root / "control").mkdir()
    (root / "control" / "guide.py").write_text("x = 1\n")  # a declaration
    (root / "motion_kernels.py").write_text("y = 2\n")
    (root / "speech").mkdir()
    cache = root / "__pycache__"
    cache.mkdir()
    kept = cache / "motion_kernels.cpython-311.pyc"
    kept.write_bytes(b"pyc")
    other = root / "speech" / "__pycache__"
    other.mkdir()
    (other / "vocoder_kernels.pull-10.py311.nbi").write_bytes(b"numba")  # not listed: kept
    sources, compiled_ = ("control/guide.py", "motion_kernels.py"), ("motion_kernels.py",)

    def compiled() -> list[Path]:
        for name in ("motion_kernels.tick-104.py311.nbi", "motion_kernels.tick-104.py311.1.nbc"):
            (cache / name).write_bytes(b"numba")
        return sorted(cache.glob("*.nb[ic]"))

    compiled()
    assert clear_stale_cache(root, sources, compiled_)  # no digest yet: the origin is unknown
    assert not list(cache.glob("*.nb[ic]")) and kept.is_file()
    files = compiled()
    assert not clear_stale_cache(root, sources, compiled_)  # unchanged sources: kept
    assert sorted(cache.glob("*.nb[ic]")) == files
    (root / "control" / "guide.py").write_text("x = 3\n")  # another file than the kernel's
    assert clear_stale_cache(root, sources, compiled_)
    assert not list(cache.glob("*.nb[ic]")) and kept.is_file()
    assert len(list(other.glob("*.nbi"))) == 1
    blocked = tmp_path / "blocked"
    blocked.write_text("")
    assert not clear_stale_cache(blocked, sources, compiled_)  # nothing can be written: no error
