"""Every command the README shows runs as written, with a tiny budget.

The README's ``bash`` blocks are its commands, run block by block (a block's commands in order,
each block in a fresh directory holding links to the checkout's ``configs``, ``langenv`` and
``models``) with the interpreter's ``bin`` first on ``PATH``, so ``langctrl`` and ``python`` are
the installed ones. :data:`BUDGET` names every command line of the README: how the test shrinks
it (each replacement must apply), or why it does not run it. A README edit that adds or changes a
command fails :func:`test_every_readme_command_has_a_budget` until the command is given one, so
no command goes untested by accident. The ``python`` blocks run as written.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
FENCE = re.compile(r"^```(\w+)\n(.*?)^```$", re.MULTILINE | re.DOTALL)
TIMEOUT = 600  # s per block


@dataclass(frozen=True)
class Shrink:
    """Run the command with these ``(old, new)`` replacements (each must occur in it)."""

    replace: tuple[tuple[str, str], ...] = ()
    slow: bool = False


@dataclass(frozen=True)
class Skip:
    """Do not run the command, for this reason."""

    reason: str


#: The phrase chooser's recipe counts phrase choices (about 6 a session); one rollout (2 x 512).
CHOICE_BUDGET = (
    "--total-timesteps 32 --n-envs 2 --eval-freq 32 --checkpoint-freq 32 --n-eval-episodes 1 "
    "--no-progress-bar --no-tensorboard"
)
FAKE_UR = "--host 127.0.0.1 --fake"

#: Every command line of the README -> how the test runs it.
BUDGET: dict[str, Shrink | Skip] = {
    'pip install -c constraints.txt -e ".[dev,sweep,docs]"': Skip(
        "the set-up line: CI (.ci/run) runs it on a fresh clone before this suite"
    ),
    "python -m pytest -q -n 2": Skip("the suite itself: CI (.ci/run) runs it"),
    "langctrl compare --policies ac,lc-noap,lc --users synthetic:12 --seed 0 --out out/compare": (
        Shrink((("synthetic:12", "synthetic:1"),))
    ),
    "langctrl train --config configs/ppo_speech.yaml --seed 3000000 --out runs/speech": Shrink(
        (("--out runs/speech", f"--out runs/speech {CHOICE_BUDGET}"),), slow=True
    ),
    # The shipped recipe's checkpoint (8 192 choices); the shrunk run's only one is at 1 024.
    "langctrl export runs/speech --steps 8192 --terminal 1 --out runs/speech/best": Shrink(
        (("--steps 8192", "--steps 1024"),), slow=True
    ),
    "langctrl generalise --model runs/speech/best.zip --users 48 --out out/val": Shrink(
        (("--users 48", "--users 1 --policies lc,lc-fill-end --n-boot 100"),), slow=True
    ),
    "langctrl exercises --out out/exercises": Shrink(
        (("--out", "--users synthetic:1 --exercises hand_to_mouth --out"),), slow=True
    ),
    "langctrl generalise --model models/ppo_speech.zip --model "
    "models/speech_seeds/ppo_speech_s1000000.zip --model "
    "models/speech_seeds/ppo_speech_s2000000.zip --role test --users 48 --population both "
    "--out out/speech_test": Skip(
        "the learned phrase chooser's look at the test sets (HISTORY.md records it); "
        "tools/results.py runs it for the README's table, the generalise job is tested on "
        "validation people"
    ),
    "langctrl exercise list": Shrink(),
    "cp -r langenv/assets/exercises my_exercises": Shrink(),
    "langctrl exercise check my_exercises/hand_to_mouth.yaml": Shrink(),
    "langctrl speech author my_exercises/scripts/hand_to_mouth_lc.txt --out my_script.yaml "
    "--exercise my_exercises/hand_to_mouth.yaml": Shrink(),
    "langctrl speech check my_script.yaml --coverage": Shrink(),
    "langctrl compare --policies ac,lc-noap,lc --exercise my_exercises/hand_to_mouth.yaml "
    "--graph my_script.yaml --users synthetic:12 --out out/mine": Shrink(
        (("synthetic:12", "synthetic:1"), ("--out", "--no-audio --no-figures --out"))
    ),
    "langctrl play": Shrink((("play", "play --headless --seconds 1 --audio-out viewer.wav"),)),
    "langctrl play --headless --seconds 10 --audio-out live.wav": Shrink(
        (("--seconds 10", "--seconds 1"),)
    ),
    'pip install -c constraints.txt -e ".[ur]"': Skip(
        "installs ur-rtde; the bridge's tests run against its fake"
    ),
    "langctrl robot --host 127.0.0.1 --fake --dry-run": Shrink(),
    "langctrl robot --config configs/ur.yaml --dry-run": Shrink(
        (("--dry-run", f"{FAKE_UR} --dry-run"),)
    ),
    "langctrl robot --config configs/ur.yaml --log-out session.csv": Shrink(
        (("--log-out", f"{FAKE_UR} --yes --audio-out session.wav --log-out"),)
    ),
}


def readme_blocks(text: str) -> list[tuple[str, list[str]]]:
    """The README's code blocks to run: ``(language, commands)`` for ``bash`` (one command per
    line, comments and continuations handled) and ``(python, [source])``."""
    blocks = []
    for match in FENCE.finditer(text):
        lang, body = match[1], match[2]
        if lang == "bash":
            lines = body.replace("\\\n", " ").splitlines()
            commands = [re.sub(r"\s+", " ", line).strip() for line in lines]
            blocks.append((lang, [c for c in commands if c and not c.startswith("#")]))
        elif lang == "python":
            blocks.append((lang, [body]))
    return blocks


def _blocks() -> list[tuple[str, list[str]]]:
    return readme_blocks(README.read_text(encoding="utf-8"))


def test_every_readme_command_has_a_budget() -> None:
    shown = [c for lang, commands in _blocks() if lang == "bash" for c in commands]
    unknown = [c for c in shown if c not in BUDGET]
    assert unknown == [], f"README commands without a budget in tests/test_readme.py: {unknown}"
    stale = sorted(set(BUDGET) - set(shown))
    assert stale == [], f"budgets for commands the README no longer shows: {stale}"


def test_the_parser_reads_commands_and_comments() -> None:
    text = "x\n```bash\n# a comment\nlangctrl a \\\n  --b 1\n\nlangctrl c\n```\n```text\nno\n```\n"
    assert readme_blocks(text) == [("bash", ["langctrl a --b 1", "langctrl c"])]


def _command(shown: str) -> str | None:
    rule = BUDGET[shown]
    if isinstance(rule, Skip):
        return None
    command = shown
    for old, new in rule.replace:
        assert old in command, f"budget rule {old!r} does not apply to {shown!r}"
        command = command.replace(old, new, 1)
    return command


def _workdir(tmp_path: Path) -> Path:
    for name in ("configs", "langenv", "models"):
        (tmp_path / name).symlink_to(REPO / name, target_is_directory=True)
    return tmp_path


def _params() -> list[Any]:
    params = []
    for i, (lang, commands) in enumerate(_blocks()):
        slow = lang == "bash" and any(
            isinstance(r := BUDGET.get(c), Shrink) and r.slow for c in commands
        )
        marks = [pytest.mark.slow] if slow else []
        params.append(pytest.param(i, marks=marks, id=f"{i}-{lang}-{commands[0][:40]}"))
    return params


@pytest.mark.parametrize("index", _params())
def test_readme_block_runs(index: int, tmp_path: Path) -> None:
    lang, commands = _blocks()[index]
    cwd = _workdir(tmp_path)
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    if lang == "python":
        script = cwd / "readme_block.py"
        script.write_text(commands[0], encoding="utf-8")
        runs = [f"{sys.executable} {script.name}"]
    else:
        runs = [c for c in (_command(shown) for shown in commands) if c is not None]
    if not runs:
        pytest.skip("; ".join(r.reason for c in commands if isinstance(r := BUDGET[c], Skip)))
    for command in runs:
        res = subprocess.run(
            ["bash", "-c", command],
            cwd=cwd,
            env=env,
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            check=False,
        )
        assert res.returncode == 0, f"{command}\n{res.stdout[-2000:]}\n{res.stderr[-3000:]}"


def test_the_environment_example_runs_its_policy_at_the_policys_rate(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The README's Python example steps the env at the rate its policy holds its law at (an
    analytic policy's 500 Hz), and its session ends with speech and motion together."""
    (source,) = [c[0] for lang, c in _blocks() if lang == "python" and "gym.make" in c[0]]
    monkeypatch.chdir(REPO)
    scope: dict[str, Any] = {}
    exec(compile(source, "README.md", "exec"), scope)
    env, policy, info = scope["env"], scope["policy"], scope["info"]
    assert env.unwrapped.decision_hz == policy.decision_hz
    assert info["am"] is not None and abs(info["am"]) <= 1.0
    assert "AM = " in capsys.readouterr().out
