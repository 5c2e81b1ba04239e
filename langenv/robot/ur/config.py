"""URConfig: how a real UR is set up for LangCtrl, checked before anything moves.

A YAML file (``configs/ur.yaml`` is the example) holds what a lab changes; units in the file are
m, kg, deg, s, m/s, Hz, and become SI (rad) once, at load:

| key | type, unit | default | meaning |
|---|---|---|---|
| ``host`` | str | (required) | the robot's or URSim's host name or address |
| ``frequency`` | Hz | 500 | RTDE and control frequency: the loop's tick is 2 ms, an e-series controller |
| ``min_version`` | str | ``"5.4"`` | lowest PolyScope version accepted (e-series: 500 Hz RTDE) |
| ``payload_mass`` | kg | 0.6 | the handle's mass, as set on the robot (checked, never set) |
| ``payload_cog`` | [m] x3 | [0, 0, 0.05] | its centre of gravity from the flange |
| ``tcp_offset`` | [m x3, deg x3] | [0, 0, 0.1, 0, 0, 0] | the TCP (the handle's grip point) from the flange, as set on the robot |
| ``mass_tolerance`` | kg | 0.05 | payload mass check |
| ``cog_tolerance`` | m | 0.005 | payload centre of gravity check |
| ``tcp_tolerance`` | m | 0.001 | TCP offset check (translation; rotation within 0.5 deg) |
| ``exercise_origin`` | [m] x3 | [0, 0, 0] | where the exercise's frame sits in the robot's base frame (added to the path) |
| ``approach_speed`` | m/s | 0.05 | speed of the confirmed move to the exercise's start |
| ``max_approach`` | m | 0.3 | a start farther than this from the TCP is refused (move the arm closer by hand) |
| ``speed_acceleration`` | m/s^2 | 1.0 | ``speedL``'s acceleration during the session |
| ``stop_deceleration`` | m/s^2 | 2.0 | ``speedStop``'s deceleration (0.5 m/s stops within 6 cm) |
| ``watchdog_hz`` | Hz | 50 | RTDE watchdog: the controller stops the arm if our loop sends nothing for 1/this s |
| ``connect_timeout`` | s | 2.0 | no answer from the host within this is an error |
| ``rt_priority`` | int | 0 | ur-rtde's real-time priority for its threads (0: the library's default; needs the right to set it) |
| ``joint_lower``, ``joint_upper`` | [deg] x6 | ±360 (elbow ±180, as an e-series UR5) | the joints' ranges for the monitor's ``joint_margin`` |
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from langenv.errors import ConfigError
from langenv.validation import frozen_vector

__all__ = ["URConfig", "load_ur_config"]

_DEG = math.pi / 180.0


def _array(values: Any, n: int, name: str) -> NDArray[np.float64]:
    return frozen_vector(values, f"URConfig.{name}", ConfigError, n)


@dataclass(frozen=True, eq=False)
class URConfig:
    """A UR's set-up (SI units; the file's table is in this module's docstring).

    Raises:
        ConfigError: a field out of its range or of the wrong shape (the field named).
    """

    host: str
    frequency: float = 500.0
    min_version: str = "5.4"
    payload_mass: float = 0.6
    payload_cog: NDArray[np.float64] = field(default_factory=lambda: np.array([0.0, 0.0, 0.05]))
    tcp_offset: NDArray[np.float64] = field(
        default_factory=lambda: np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0])
    )
    mass_tolerance: float = 0.05
    cog_tolerance: float = 0.005
    tcp_tolerance: float = 0.001
    exercise_origin: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    approach_speed: float = 0.05
    max_approach: float = 0.3
    speed_acceleration: float = 1.0
    stop_deceleration: float = 2.0
    watchdog_hz: float = 50.0
    connect_timeout: float = 2.0
    rt_priority: int = 0
    joint_lower: NDArray[np.float64] = field(
        default_factory=lambda: np.array([-2, -2, -1, -2, -2, -2]) * math.pi
    )
    joint_upper: NDArray[np.float64] = field(
        default_factory=lambda: np.array([2, 2, 1, 2, 2, 2]) * math.pi
    )

    def __post_init__(self) -> None:
        if not isinstance(self.host, str) or not self.host.strip():
            raise ConfigError(f"URConfig.host must be a host name or address, got {self.host!r}")
        if not re.fullmatch(r"[0-9]+(\.[0-9]+)*", str(self.min_version)):
            raise ConfigError(
                f"URConfig.min_version must look like '5.4', got {self.min_version!r}"
            )
        positive = (
            "payload_mass",
            "mass_tolerance",
            "cog_tolerance",
            "tcp_tolerance",
            "approach_speed",
            "max_approach",
            "speed_acceleration",
            "stop_deceleration",
            "watchdog_hz",
            "connect_timeout",
        )
        for name in positive:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ConfigError(f"URConfig.{name} must be a number, got {value!r}")
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"URConfig.{name} must be finite and > 0, got {value!r}")
            object.__setattr__(self, name, float(value))
        if isinstance(self.rt_priority, bool) or not isinstance(self.rt_priority, int):
            raise ConfigError(f"URConfig.rt_priority must be an integer, got {self.rt_priority!r}")
        if not 0 <= self.rt_priority <= 99:
            raise ConfigError(f"URConfig.rt_priority must be in [0, 99], got {self.rt_priority}")
        if self.frequency != 500.0:
            raise ConfigError(
                f"URConfig.frequency must be 500 Hz (the loop's 2 ms tick; an e-series "
                f"controller), got {self.frequency!r}"
            )
        if self.approach_speed > 0.25:
            raise ConfigError(
                f"URConfig.approach_speed must be <= 0.25 m/s (a slow move near a person), "
                f"got {self.approach_speed}"
            )
        for name, n in (
            ("payload_cog", 3),
            ("tcp_offset", 6),
            ("exercise_origin", 3),
            ("joint_lower", 6),
            ("joint_upper", 6),
        ):
            object.__setattr__(self, name, _array(getattr(self, name), n, name))
        if not np.all(self.joint_lower < self.joint_upper):
            raise ConfigError("URConfig.joint_lower must be below joint_upper for every joint")

    @property
    def period(self) -> float:
        """Control period (s)."""
        return 1.0 / self.frequency


_ANGLES = {"tcp_offset": slice(3, 6), "joint_lower": slice(0, 6), "joint_upper": slice(0, 6)}


def load_ur_config(path: str | Path, **overrides: Any) -> URConfig:
    """Read a UR set-up file (YAML); ``overrides`` (e.g. ``host``) win over the file.

    Raises:
        ConfigError: naming the file: unreadable, not a mapping, unknown keys (all listed, with
            the known ones), or a bad value (the field named).
    """
    import yaml

    from langenv.validation import yaml_text

    path = Path(path)
    try:
        data = yaml.safe_load(yaml_text(path.read_text(encoding="utf-8"), path))
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"{path}: cannot read the UR set-up ({exc})") from exc
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: must be a mapping of keys to values")
    known = {f.name for f in fields(URConfig)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ConfigError(
            f"{path}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}"
        )
    values: dict[str, Any] = dict(data)
    try:
        for key, part in _ANGLES.items():
            if key in values:
                arr = np.array(values[key], dtype=np.float64)
                arr[part] = arr[part] * _DEG
                values[key] = arr
        values.update({k: v for k, v in overrides.items() if v is not None})
        if "host" not in values:
            raise ConfigError("host is missing (give it in the file or with --host)")
        return URConfig(**values)
    except (ConfigError, TypeError, ValueError, IndexError) as exc:
        raise ConfigError(f"{path}: {exc}") from None
