"""Clips are a pure function of their text and settings, and the shipped ones are pinned.

eSpeak NG carries state from one utterance to the next (``langenv/speech/espeak_worker.py``);
these tests check that what a process said before, and which process says it, no longer matter,
and that every shipped phrase's clip, made on a new machine (an empty cache), is the one the
committed manifest records.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import subprocess
import sys
from pathlib import Path

import pytest

from langenv.errors import AudioError
from langenv.speech import manifest
from langenv.speech.audio import ClipLibrary, ESpeakEngine

SAY_ALL = """
import hashlib, json, sys
from langenv.speech.audio import ClipLibrary
texts = json.loads(sys.argv[1])
lib = ClipLibrary(disk_cache=False)
print(json.dumps({t: hashlib.sha256(lib.synthesize(t).tobytes()).hexdigest() for t in texts}))
"""


def _digests(texts: list[str]) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", SAY_ALL, json.dumps(texts)], stdout=subprocess.PIPE, text=True
    )


@pytest.mark.portable
def test_shipped_clips_made_in_an_empty_cache_match_the_manifest(tmp_path: Path) -> None:
    made = manifest.build(ClipLibrary(cache_dir=tmp_path))
    problems = manifest.compare(made, manifest.load())
    assert not problems, "clips differ from langenv/assets/tts_manifest.json:\n" + "\n".join(
        problems
    )
    assert len(made["clips"]) >= 80


def test_two_processes_saying_every_text_in_opposite_orders_at_once_agree() -> None:
    texts = sorted(manifest.load()["clips"])
    forward, backward = _digests(texts), _digests(texts[::-1])  # both run at the same time
    out = [json.loads(p.communicate(timeout=300)[0]) for p in (forward, backward)]
    assert forward.returncode == backward.returncode == 0
    differ = [t for t in texts if out[0][t] != out[1][t]]
    assert not differ, f"{len(differ)} texts differ with the order, e.g. {differ[:3]}"
    pinned = manifest.load()["clips"]
    assert all(out[0][t] == pinned[t]["sha256"] for t in texts)


def test_what_was_said_before_does_not_change_a_clip() -> None:
    text = "Now move your hand away from your body."
    first = ClipLibrary(disk_cache=False).synthesize(text)
    lib = ClipLibrary(disk_cache=False)
    for other in ("Keep going.", "Slowly, all the way out.", "And back again."):
        lib.synthesize(other)
    engine = ESpeakEngine.get()
    again = engine.synthesize(text, lib.voice, lib.rate, lib.pitch)
    assert again.size > 0
    assert ClipLibrary(disk_cache=False).synthesize(text).tobytes() == first.tobytes()


def _child_digest(text: str, queue: multiprocessing.Queue[str]) -> None:
    y = ClipLibrary(disk_cache=False).synthesize(text)
    queue.put(hashlib.sha256(y.tobytes()).hexdigest())


def test_a_forked_process_starts_its_own_worker_and_gets_the_same_clip() -> None:
    text = "One more good one."
    ClipLibrary(disk_cache=False).synthesize("Keep going.")  # this process's worker is up
    ctx = multiprocessing.get_context("fork")
    queue: multiprocessing.Queue[str] = ctx.Queue()
    child = ctx.Process(target=_child_digest, args=(text, queue))
    child.start()
    digest = queue.get(timeout=60)
    child.join(60)
    assert child.exitcode == 0
    assert digest == manifest.load()["clips"][text]["sha256"]


def test_an_unknown_voice_is_a_named_error() -> None:
    with pytest.raises(AudioError, match="no voice 'xx-nowhere'"):
        ClipLibrary(disk_cache=False, voice="xx-nowhere").synthesize("Hello.")
    assert ClipLibrary(disk_cache=False).synthesize("Hello.").size > 0  # the worker goes on


def test_compare_names_each_changed_setting_and_text() -> None:
    pinned = manifest.load()
    made = json.loads(json.dumps(pinned))
    text = sorted(made["clips"])[0]
    made["clips"][text]["samples"] += 3
    made["rate"] = 160
    problems = manifest.compare(made, pinned)
    assert any(p.startswith("rate: pinned 150, now 160") for p in problems)
    assert any(text in p and "samples now" in p for p in problems)
    assert len(problems) == 2


def test_manifest_cli_passes_on_the_shipped_clips() -> None:
    from langctrl.jobs import tts_manifest

    assert tts_manifest.main([]) == 0


def test_the_worker_ignores_ctrl_c_and_ends_with_its_input() -> None:
    """Ctrl-C at a terminal reaches the whole process group: the worker must not print a
    traceback then (the client says what an interrupt means), and it ends when its input ends."""
    import signal

    from langenv.speech import espeak_worker

    proc = subprocess.Popen(
        [sys.executable, espeak_worker.__file__],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert proc.stdout is not None and proc.stdin is not None
    assert json.loads(proc.stdout.readline())["sr"] > 0
    proc.send_signal(signal.SIGINT)
    proc.stdin.write(b'{"text": "Hello.", "voice": "en-us", "rate": 150, "pitch": 50}\n')
    proc.stdin.flush()
    n = json.loads(proc.stdout.readline())["n"]
    assert len(proc.stdout.read(2 * n)) == 2 * n
    proc.stdin.close()
    assert proc.wait(timeout=30) == 0
    assert proc.stderr is not None and proc.stderr.read() == b""
