"""``python -m bench.safety``: fuzz the safety layer with adversarial users and print the figures.

Each episode draws a policy (LC, AC or random actions) and an adversarial user (seeded from the
episode's seed): a person pushing up to 200 N in random, sideways, along-path or along-velocity
directions, steadily, in bursts, as noise, oscillating near the guide's resonance, or ramping up
through the force limit. At every step the run checks that nothing is NaN, the observation lies
in its space and, unless the episode ends in a protective stop that says why, that the hand's
speed stays within the speed limit (+5 %) and its distance from the path within the deviation
limit (+1 cm). Prints one JSON object: episodes, steps, stops by limit, the highest hand speed and
path deviation seen (over all steps, and over steps not ended by a stop), and violations.

    python -m bench.safety --episodes 88 --seconds 60
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from langenv.robot.safety import STOP_LIMITS, SafetyLimits
from langenv.users import CallableUser

__all__ = ["ADVERSARIES", "FuzzResult", "adversary", "fuzz", "fuzz_episode"]

#: Kinds of adversarial users.
ADVERSARIES: tuple[str, ...] = (
    "random_steps",
    "sideways",
    "along_velocity",
    "against_velocity",
    "along_path",
    "noise",
    "resonant",
    "ramp",
)

_ENVS: dict[tuple[str, SafetyLimits, int], Any] = {}

SPEED_SLACK = 0.05  # relative: a step's top speed may exceed the limit by 5 % (measurement)
DEVIATION_SLACK = 0.01  # m


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-9 else np.zeros(3)


def adversary(kind: str, rng: np.random.Generator, f_max: float = 200.0) -> Callable[..., Any]:
    """An adversarial force law ``f(t, hand_velocity, tangent) -> (3,)`` N, parameters drawn
    from ``rng``.

    Args:
        kind: One of :data:`ADVERSARIES`.
        rng: Source of the user's parameters (and of its noise).
        f_max: Largest force it applies (N).
    """
    mag = float(rng.uniform(0.2, 1.0)) * f_max
    direction = _unit(rng.normal(size=3))
    if kind == "random_steps":
        period = float(rng.uniform(0.2, 3.0))
        table = [(rng.uniform(0.0, f_max), _unit(rng.normal(size=3))) for _ in range(200)]

        def steps(t: float, v: np.ndarray, b: np.ndarray) -> np.ndarray:
            m, d = table[int(t / period) % len(table)]
            return m * d

        return steps
    if kind == "sideways":
        up = float(rng.uniform(-1.0, 1.0))

        def sideways(t: float, v: np.ndarray, b: np.ndarray) -> np.ndarray:
            side = _unit(np.cross(b, (0.0, 0.0, 1.0)) + up * np.array((0.0, 0.0, 1.0)))
            return mag * side

        return sideways
    if kind in ("along_velocity", "against_velocity"):
        sign = 1.0 if kind == "along_velocity" else -1.0

        def with_velocity(t: float, v: np.ndarray, b: np.ndarray) -> np.ndarray:
            return sign * mag * np.asarray(v) / max(float(np.linalg.norm(v)), 1e-3)

        return with_velocity
    if kind == "along_path":
        sign = float(rng.choice([-1.0, 1.0]))
        return lambda t, v, b: sign * mag * np.asarray(b)
    if kind == "noise":
        return lambda t, v, b: rng.normal(0.0, mag / 2.0, 3)
    if kind == "resonant":
        freq = float(rng.uniform(0.1, 3.0))  # Hz; the guide's resonance is near 0.28 Hz
        return lambda t, v, b: mag * math.sin(2 * math.pi * freq * t) * direction
    if kind == "ramp":
        rate = float(rng.uniform(5.0, 40.0))  # N/s
        return lambda t, v, b: min(rate * t, f_max) * direction
    raise ValueError(f"unknown adversary {kind!r}; known: {ADVERSARIES}")


@dataclass
class FuzzResult:
    """Figures of a fuzz run (see the module docstring)."""

    episodes: int = 0
    steps: int = 0
    stops: Counter[str] = field(default_factory=Counter)
    max_speed: float = 0.0
    max_deviation: float = 0.0
    max_speed_unstopped: float = 0.0
    max_deviation_unstopped: float = 0.0
    violations: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {
            "episodes": self.episodes,
            "steps": self.steps,
            "stops": {k: self.stops.get(k, 0) for k in STOP_LIMITS},
            "episodes_without_stop": self.episodes - sum(self.stops.values()),
            "max_hand_speed": round(self.max_speed, 4),
            "max_path_deviation": round(self.max_deviation, 4),
            "max_hand_speed_without_stop": round(self.max_speed_unstopped, 4),
            "max_path_deviation_without_stop": round(self.max_deviation_unstopped, 4),
            "violations": self.violations,
        }


def fuzz_episode(
    seed: int,
    result: FuzzResult,
    *,
    seconds: float = 60.0,
    limits: SafetyLimits | None = None,
    kind: str | None = None,
    policy: str | None = None,
) -> None:
    """Run one adversarial episode and add its figures (and any violation) to ``result``.

    Args:
        seed: Seeds the user's parameters, the policy's draw and the env.
        result: Accumulates the figures.
        seconds: Episode length (s) at 25 decisions per second.
        limits: Safety limits of the env (default :class:`SafetyLimits`).
        kind: The adversary (default: drawn from :data:`ADVERSARIES`).
        policy: ``"lc"``, ``"ac"`` or ``"random"`` (default: drawn).
    """
    import gymnasium as gym

    import langenv
    from langenv.exercise.script import speak
    from policies import load_policy

    rng = np.random.default_rng(seed)
    kind = kind or str(rng.choice(ADVERSARIES))
    policy = policy or str(rng.choice(["lc", "ac", "random"]))
    pol = load_policy("lc" if policy == "random" else policy)
    lim = limits if limits is not None else SafetyLimits()
    graph = speak(pol).ref  # the study's exercise's graph for the policy's role
    key = (graph, lim, round(seconds * 25))
    env = _ENVS.get(key)
    if env is None:  # one env per graph and limits: building one costs up to seconds
        env = _ENVS[key] = gym.make(
            langenv.ENV_ID,
            phrase_graph=graph,
            safety=lim,
            max_episode_steps=key[2],
        )
    obs, info = env.reset(seed=seed, options={"user": CallableUser(adversary(kind, rng))})
    pol.reset()
    space = env.observation_space
    where = f"seed {seed} ({kind}, {policy})"
    done = False
    while not done:
        action = env.action_space.sample() if policy == "random" else pol.act(obs)
        obs, reward, terminated, truncated, info = env.step(action)
        result.steps += 1
        done = terminated or truncated
        speed, dev = float(info["max_hand_speed"]), float(info["path_deviation"])
        result.max_speed = max(result.max_speed, speed)
        result.max_deviation = max(result.max_deviation, dev)
        stop = info["safety_stop"]
        if not (np.all(np.isfinite(obs)) and math.isfinite(reward)) or not space.contains(obs):
            result.violations.append(f"{where}: NaN or observation outside its space")
        if stop is not None:
            if stop not in STOP_LIMITS or not terminated or not info["safety_message"]:
                result.violations.append(f"{where}: stop {stop!r} without reason or end")
            result.stops[stop] += 1
            continue
        result.max_speed_unstopped = max(result.max_speed_unstopped, speed)
        result.max_deviation_unstopped = max(result.max_deviation_unstopped, dev)
        if speed > lim.max_speed * (1 + SPEED_SLACK) or dev > lim.max_deviation + DEVIATION_SLACK:
            result.violations.append(
                f"{where}: t={info['time']:.3f} s speed {speed:.3f} m/s, deviation {dev:.3f} m "
                "without a protective stop"
            )
    result.episodes += 1


def fuzz(episodes: int, seconds: float = 60.0, first_seed: int = 0) -> FuzzResult:
    """Run ``episodes`` adversarial episodes (seeds ``first_seed`` onwards)."""
    result = FuzzResult()
    for k in range(episodes):
        fuzz_episode(first_seed + k, result, seconds=seconds)
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.safety", description=__doc__)
    parser.add_argument("--episodes", type=int, default=88)
    parser.add_argument("--seconds", type=float, default=60.0, help="episode length (s)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first episode")
    args = parser.parse_args(argv)
    if args.episodes < 1 or not args.seconds > 0:
        parser.error("--episodes must be >= 1 and --seconds > 0")
    t0 = time.perf_counter()
    result = fuzz(args.episodes, args.seconds, args.seed)
    out = result.as_dict()
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(out))
    return 1 if result.violations else 0


if __name__ == "__main__":
    sys.exit(main())
