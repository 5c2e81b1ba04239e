"""eSpeak NG in a worker process that synthesises every phrase from the same clean state.

eSpeak NG keeps state from one utterance to the next that no API call resets: the phase of its
pitch flutter (``static int Flutter_ix`` in ``AdvanceParameters``, ``wavegen.c``) runs on across
calls, so the same text came out a few samples longer or shorter depending on what the process
had said before (measured: 80 of the 86 texts of the shipped graphs differed between two orders).
Re-initialising the library does not reset such function-local statics.

This module runs as its own process (``python espeak_worker.py``; standard library and
``espeakng-loader`` only, so it starts in a few tens of milliseconds). It loads and initialises
the library once and synthesises nothing itself; for each request it forks a child, which
inherits that pristine state, says the one text and exits. Every clip is therefore the first
utterance of a freshly initialised engine: a pure function of the text, the voice settings and
the engine's version, whatever was asked before, in whichever process. The worker is
single-threaded, so forking it is safe; where ``os.fork`` does not exist (Windows) the worker
answers one request and exits, and the client starts a new one for the next.

Protocol (binary pipes): the worker first writes one JSON line ``{"sr": int, "version": str,
"one_shot": bool}`` (or ``{"error": str}``). A request is one JSON line ``{"text", "voice",
"rate", "pitch"}``; the answer is one JSON line ``{"n": samples}`` followed by ``2 n`` bytes of
native-endian int16 samples, or ``{"error": str}``. End of input ends the worker.
:class:`~langenv.speech.audio.ESpeakEngine` is the client.
"""

from __future__ import annotations

import ctypes
import json
import os
import signal
import sys
from typing import Any, BinaryIO

# eSpeak NG API constants (speak_lib.h)
_AUDIO_OUTPUT_SYNCHRONOUS = 2
_POS_CHARACTER = 1
_ESPEAK_CHARS_UTF8 = 1
_ESPEAK_RATE = 1
_ESPEAK_VOLUME = 2
_ESPEAK_PITCH = 3
_EE_OK = 0
_SYNTH_CALLBACK = ctypes.CFUNCTYPE(
    ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.c_void_p
)
FALLBACK_VOICE = {"en-us": "en"}
"""A voice tried when the asked one is missing from the library's data."""


class _Library:
    """The initialised eSpeak NG library (ctypes), before any utterance."""

    def __init__(self) -> None:
        import espeakng_loader

        lib_path = espeakng_loader.get_library_path()
        data_path = espeakng_loader.get_data_path()
        lib = ctypes.CDLL(lib_path)
        lib.espeak_Initialize.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_int]
        lib.espeak_Initialize.restype = ctypes.c_int
        lib.espeak_SetSynthCallback.argtypes = [_SYNTH_CALLBACK]
        lib.espeak_SetSynthCallback.restype = None
        lib.espeak_SetParameter.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int]
        lib.espeak_SetParameter.restype = ctypes.c_int
        lib.espeak_SetVoiceByName.argtypes = [ctypes.c_char_p]
        lib.espeak_SetVoiceByName.restype = ctypes.c_int
        lib.espeak_Synth.argtypes = [
            ctypes.c_void_p,
            ctypes.c_size_t,
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.c_uint,
            ctypes.c_uint,
            ctypes.c_void_p,
            ctypes.c_void_p,
        ]
        lib.espeak_Synth.restype = ctypes.c_int
        lib.espeak_Info.argtypes = [ctypes.c_void_p]
        lib.espeak_Info.restype = ctypes.c_char_p
        sr = lib.espeak_Initialize(_AUDIO_OUTPUT_SYNCHRONOUS, 0, data_path.encode(), 0)
        if sr <= 0:
            raise RuntimeError(f"eSpeak NG failed to initialise with data at {data_path}")
        self.lib = lib
        self.sr = int(sr)
        self.version = (lib.espeak_Info(None) or b"unknown").decode()
        self._chunks: list[bytes] = []
        self._callback = _SYNTH_CALLBACK(self._collect)  # keep a reference: C holds a pointer
        lib.espeak_SetSynthCallback(self._callback)

    def _collect(self, wav: Any, n: int, _events: Any) -> int:
        if n > 0 and wav:
            self._chunks.append(ctypes.string_at(wav, 2 * n))
        return 0  # 0: go on synthesising

    def say(self, text: str, voice: str, rate: int, pitch: int) -> bytes:
        """``text`` spoken: int16 samples at :attr:`sr` as bytes.

        Raises:
            RuntimeError: when the voice is missing or the library reports an error.
        """
        lib = self.lib
        for name in (voice, FALLBACK_VOICE[voice]) if voice in FALLBACK_VOICE else (voice,):
            if lib.espeak_SetVoiceByName(name.encode()) == _EE_OK:
                break
        else:
            raise RuntimeError(f"eSpeak NG has no voice {voice!r}")
        lib.espeak_SetParameter(_ESPEAK_RATE, int(rate), 0)
        lib.espeak_SetParameter(_ESPEAK_PITCH, int(pitch), 0)
        lib.espeak_SetParameter(_ESPEAK_VOLUME, 100, 0)
        data = text.encode("utf-8")
        buf = ctypes.create_string_buffer(data)
        self._chunks = []
        err = lib.espeak_Synth(
            buf, len(data) + 1, 0, _POS_CHARACTER, 0, _ESPEAK_CHARS_UTF8, None, None
        )
        if err != _EE_OK:
            raise RuntimeError(f"eSpeak NG failed (error {err}) to synthesise {text!r}")
        return b"".join(self._chunks)


def _answer(lib: _Library, request: dict[str, Any]) -> bytes:
    """The reply to one request, from this (clean) process: header line and samples."""
    try:
        samples = lib.say(
            str(request["text"]), str(request["voice"]), int(request["rate"]), int(request["pitch"])
        )
    except (RuntimeError, KeyError, TypeError, ValueError) as exc:
        return _line({"error": str(exc)})
    return _line({"n": len(samples) // 2}) + samples


def _answer_in_child(lib: _Library, request: dict[str, Any]) -> bytes:
    """The reply from a forked child: the library's state as it was after initialisation."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: one utterance, then gone without running any Python clean-up
        code = 0
        try:
            os.close(r)
            with os.fdopen(w, "wb") as out:
                out.write(_answer(lib, request))
        except BaseException:
            code = 1
        os._exit(code)
    os.close(w)
    with os.fdopen(r, "rb") as inp:
        reply = inp.read()
    _, status = os.waitpid(pid, 0)
    if status != 0 or not reply:
        return _line({"error": f"the eSpeak NG child process failed (wait status {status})"})
    return reply


def _line(obj: dict[str, Any]) -> bytes:
    return json.dumps(obj).encode() + b"\n"


def serve(inp: BinaryIO, out: BinaryIO) -> int:
    """Answer requests from ``inp`` on ``out`` until end of input (or one, without fork)."""
    try:
        lib = _Library()
    except Exception as exc:  # any failure to load is reported to the client, which names it
        out.write(_line({"error": f"cannot load eSpeak NG: {exc}"}))
        out.flush()
        return 1
    one_shot = not hasattr(os, "fork")
    out.write(_line({"sr": lib.sr, "version": lib.version, "one_shot": one_shot}))
    out.flush()
    for raw in inp:
        try:
            request = json.loads(raw)
        except ValueError as exc:
            out.write(_line({"error": f"bad request: {exc}"}))
            out.flush()
            continue
        out.write(_answer(lib, request) if one_shot else _answer_in_child(lib, request))
        out.flush()
        if one_shot:
            break
    return 0


if __name__ == "__main__":
    # Ctrl-C at a terminal reaches the whole process group: the client decides what it means; the
    # worker ends when its input does (the client closed it or ended).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.exit(serve(sys.stdin.buffer, sys.stdout.buffer))
