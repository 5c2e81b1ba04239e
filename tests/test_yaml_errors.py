"""A YAML syntax error in any file a user writes names that file and the line, never PyYAML's
``<unicode string>``: exercises, phrase graphs, sweeps, training configs, a UR's set-up."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from langenv.errors import LangEnvError


def _exercise(path: Path) -> Any:
    from langenv.exercise import load_exercise

    return load_exercise(path)


def _graph(path: Path) -> Any:
    from langenv.speech.graph import PhraseGraph

    return PhraseGraph.load(path)


def _sweep(path: Path) -> Any:
    from eval.sweep.spec import load_spec

    return load_spec(path)


def _config(path: Path) -> Any:
    from train.config import load_config

    return load_config(path, "LangCtrl-v0")


def _ur(path: Path) -> Any:
    from langenv.robot.ur.config import load_ur_config

    return load_ur_config(path)


@pytest.mark.parametrize("load", [_exercise, _graph, _sweep, _config, _ur])
def test_a_yaml_syntax_error_names_the_file(load: Callable[[Path], Any], tmp_path: Path) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text("a: 1\nb: [unclosed\n")
    with pytest.raises(LangEnvError) as info:  # each loader's own class, all of the package's
        load(path)
    message = str(info.value)
    assert "<unicode string>" not in message
    assert f'in "{path}", line 2' in message
