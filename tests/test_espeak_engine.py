"""The eSpeak NG client (``ESpeakEngine``) keeps its protocol in step with its worker.

A request is one line out and one answer back (a header line, then ``2 n`` bytes). These tests
check what happens when an exchange does not finish: an interrupt (Ctrl-C) in the middle of one,
a worker that ends in the middle of its samples, a process forked while another thread starts
the engine. In each case the next clip must be the clip of its own text, never what was left in
a pipe by the exchange before (which the disk cache would then keep under the wrong text).
"""

from __future__ import annotations

import atexit
import multiprocessing
import sys
import textwrap
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from langenv.errors import AudioError
from langenv.speech import espeak_worker
from langenv.speech.audio import DEFAULT_PITCH, DEFAULT_RATE, DEFAULT_VOICE, ESpeakEngine

SHORT, LONG = "Keep going.", "And you're done, well done, that was very good."


def _say(engine: ESpeakEngine, text: str) -> np.ndarray:
    return engine.synthesize(text, DEFAULT_VOICE, DEFAULT_RATE, DEFAULT_PITCH)


class _InterruptedOnce:
    """A worker's stdout whose ``method`` raises KeyboardInterrupt the first time (Ctrl-C while
    the client waits on the pipe)."""

    def __init__(self, inner: Any, method: str) -> None:
        self._inner, self._method, self._fired = inner, method, False

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._inner, name)
        if name == self._method and not self._fired:

            def interrupted(*args: Any) -> Any:
                self._fired = True
                raise KeyboardInterrupt

            return interrupted
        return attr


@pytest.mark.parametrize("where", ["readline", "read"])
def test_an_interrupt_mid_request_does_not_hand_its_answer_to_the_next_text(where: str) -> None:
    engine = ESpeakEngine()
    try:
        short, long = _say(engine, SHORT), _say(engine, LONG)
        assert engine._proc is not None
        engine._proc.stdout = _InterruptedOnce(engine._proc.stdout, where)  # type: ignore[assignment]
        with pytest.raises(KeyboardInterrupt):
            _say(engine, SHORT)
        again = _say(engine, LONG)
        assert again.size == long.size, f"got {again.size} samples (SHORT has {short.size})"
        np.testing.assert_array_equal(again, long)
        np.testing.assert_array_equal(_say(engine, SHORT), short)
    finally:
        if engine._proc is not None:
            ESpeakEngine._stop(engine._proc)


def _fake_worker(tmp_path: Path, answer: str) -> Path:
    """A worker script that greets like the real one and answers every request with ``answer``
    (Python code writing to ``out``), then ends."""
    script = tmp_path / "fake_worker.py"
    script.write_text(
        textwrap.dedent(
            """
            import json, sys
            out = sys.stdout.buffer
            out.write(json.dumps({"sr": 22050, "version": "fake", "one_shot": False}).encode())
            out.write(b"\\n")
            out.flush()
            for raw in sys.stdin.buffer:
            """
        )
        + textwrap.indent(textwrap.dedent(answer), "    ")
        + "\n    out.flush()\n    sys.exit(0)\n"
    )
    return script


def test_a_worker_that_ends_inside_its_samples_is_an_error_not_a_short_clip(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fake = _fake_worker(tmp_path, "out.write(b'{\"n\": 1000}\\n' + bytes(600))")
    monkeypatch.setattr(espeak_worker, "__file__", str(fake))
    engine = ESpeakEngine()
    try:
        with pytest.raises(AudioError, match="cut short"):
            _say(engine, SHORT)
        assert engine._proc is None  # the next request starts a new worker
    finally:
        if engine._proc is not None:
            ESpeakEngine._stop(engine._proc)


def test_a_worker_that_ends_inside_an_odd_byte_is_an_audio_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fake = _fake_worker(tmp_path, "out.write(b'{\"n\": 1000}\\n' + bytes(601))")
    monkeypatch.setattr(espeak_worker, "__file__", str(fake))
    engine = ESpeakEngine()
    try:
        with pytest.raises(AudioError):
            _say(engine, SHORT)
    finally:
        if engine._proc is not None:
            ESpeakEngine._stop(engine._proc)


def test_one_shot_workers_leave_nothing_behind(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without fork (Windows) a worker serves one request and ends: each is reaped and
    forgotten, and no exit handler is added per request."""
    from langenv.speech import audio

    script = tmp_path / "one_shot_worker.py"
    script.write_text(
        "import json, sys\n"
        "out = sys.stdout.buffer\n"
        "out.write(json.dumps({'sr': 22050, 'version': 'fake', 'one_shot': True}).encode())\n"
        "out.write(b'\\n'); out.flush()\n"
        "sys.stdin.buffer.readline()\n"
        "out.write(b'{\"n\": 3}\\n' + bytes(6)); out.flush()\n"
    )
    monkeypatch.setattr(espeak_worker, "__file__", str(script))
    handlers = atexit._ncallbacks()  # CPython's count of exit handlers
    before = dict(audio._WORKERS)
    engine = ESpeakEngine()
    for _ in range(4):
        assert _say(engine, SHORT).size == 3
        assert audio._WORKERS == before and engine._proc is None
    assert atexit._ncallbacks() == handlers


def test_a_garbled_greeting_is_an_audio_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    script = tmp_path / "noisy_worker.py"
    script.write_text("print('eSpeak says hello on stdout')\nimport sys\nsys.stdin.read()\n")
    monkeypatch.setattr(espeak_worker, "__file__", str(script))
    with pytest.raises(AudioError, match="eSpeak NG worker"):
        ESpeakEngine()


def _child_says(queue: Any) -> None:
    queue.put(ESpeakEngine.get().synthesize(SHORT, DEFAULT_VOICE, DEFAULT_RATE, DEFAULT_PITCH).size)


@pytest.mark.skipif(sys.platform == "win32", reason="needs fork")
def test_a_process_forked_while_another_thread_starts_the_engine_does_not_hang() -> None:
    """``ESpeakEngine.get`` holds a class lock while it starts a worker (tens of ms); a fork
    in that window copied the lock held, and the child's first clip waited for ever."""
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    started = threading.Event()
    release = threading.Event()

    def starting() -> None:  # stands for a thread inside ESpeakEngine.get()
        with ESpeakEngine._create_lock:
            started.set()
            release.wait(30)

    thread = threading.Thread(target=starting)
    thread.start()
    started.wait(30)
    try:
        child = ctx.Process(target=_child_says, args=(queue,))
        child.start()
        child.join(60)
        hung = child.exitcode is None
        if hung:
            child.kill()
            child.join()
    finally:
        release.set()
        thread.join()
    assert not hung, "the forked child waited for a lock its parent's thread held"
    assert child.exitcode == 0
    assert queue.get(timeout=10) > 0
