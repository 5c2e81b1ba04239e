"""ForceSensor: soft deadband and Gaussian noise."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.errors import ActionError, ConfigError
from langenv.robot import ForceSensor

forces = st.lists(st.floats(-100.0, 100.0), min_size=3, max_size=3).map(np.array)
deadbands = st.floats(0.0, 30.0)


@settings(max_examples=200, deadline=None)
@given(forces, deadbands)
def test_soft_deadband_magnitude_and_direction(f: np.ndarray, deadband: float) -> None:
    out = ForceSensor(noise_std=0.0, deadband=deadband).measure(f, None)
    norm = float(np.linalg.norm(f))
    assert out.shape == (3,)
    assert float(np.linalg.norm(out)) == pytest.approx(max(0.0, norm - deadband), abs=1e-9)
    if np.linalg.norm(out) > 1e-9:  # same direction as the input
        assert float(out @ f) == pytest.approx(float(np.linalg.norm(out)) * norm, rel=1e-9)


@settings(max_examples=100, deadline=None)
@given(forces, forces, deadbands)
def test_soft_deadband_is_1_lipschitz(f1: np.ndarray, f2: np.ndarray, deadband: float) -> None:
    sensor = ForceSensor(deadband=deadband)
    gap = np.linalg.norm(sensor.measure(f1, None) - sensor.measure(f2, None))
    assert gap <= np.linalg.norm(f1 - f2) + 1e-9  # continuous, no jump at the deadband


def test_zero_below_deadband_and_identity_without_it() -> None:
    sensor = ForceSensor(deadband=5.0)
    np.testing.assert_array_equal(sensor.measure(np.array([3.0, -4.0, 0.0]), None), 0.0)
    np.testing.assert_allclose(sensor.measure(np.array([6.0, -8.0, 0.0]), None), [3.0, -4.0, 0.0])
    f = np.array([0.3, -1.2, 2.0])
    np.testing.assert_array_equal(ForceSensor(deadband=0.0).measure(f, None), f)
    assert sensor.magnitude(np.array([0.0, 0.0, 12.0]), None) == pytest.approx(7.0)


def test_no_noise_without_rng_or_std() -> None:
    f = np.array([10.0, 2.0, -1.0])
    noisy = ForceSensor(noise_std=1.0, deadband=0.0)
    np.testing.assert_array_equal(noisy.measure(f, None), f)
    quiet = ForceSensor(noise_std=0.0, deadband=0.0)
    np.testing.assert_array_equal(quiet.measure(f, np.random.default_rng(0)), f)


def test_noise_statistics_and_reproducibility() -> None:
    sensor = ForceSensor(noise_std=0.5, deadband=0.0)
    f = np.array([20.0, -3.0, 1.0])
    rng = np.random.default_rng(42)
    samples = np.array([sensor.measure(f, rng) for _ in range(4000)])
    err = samples - f
    assert np.all(np.abs(err.mean(axis=0)) < 4 * 0.5 / math.sqrt(4000))
    np.testing.assert_allclose(err.std(axis=0), 0.5, rtol=0.06)
    again = ForceSensor(noise_std=0.5, deadband=0.0).measure(f, np.random.default_rng(42))
    np.testing.assert_array_equal(again, samples[0])


def test_input_not_modified() -> None:
    f = np.array([10.0, 0.0, 0.0])
    ForceSensor(noise_std=1.0, deadband=5.0).measure(f, np.random.default_rng(1))
    np.testing.assert_array_equal(f, [10.0, 0.0, 0.0])


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"noise_std": -0.1}, "noise_std"),
        ({"noise_std": math.nan}, "noise_std"),
        ({"deadband": -1.0}, "deadband"),
        ({"deadband": math.inf}, "deadband"),
        ({"deadband": "five"}, "deadband"),
    ],
)
def test_constructor_validates(kwargs: dict[str, object], name: str) -> None:
    with pytest.raises(ConfigError, match=name):
        ForceSensor(**kwargs)  # type: ignore[arg-type]


def test_measure_validates_force() -> None:
    sensor = ForceSensor()
    with pytest.raises(ActionError, match="f must"):
        sensor.measure(np.array([np.nan, 0.0, 0.0]), None)
    with pytest.raises(ActionError, match="f must"):
        sensor.measure(np.zeros(2), None)
