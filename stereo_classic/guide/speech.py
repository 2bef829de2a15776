"""Speak the guide's events with a local, offline text-to-speech engine; or write each one as a WAV file.

Engines, first found wins: the ``espeak-ng`` (or ``espeak``) program, then the ``pyttsx3`` package (which
drives eSpeak, SAPI5 or NSSpeechSynthesizer). None is a dependency: without one, :class:`Speaker` logs one line
saying what to install and stays silent; speech never fails a run (an engine error is logged once, then the
speaker goes quiet).

A danger event (``interrupt=True``) stops what is being said before it is spoken; another message that comes while
one is being said is not spoken (it is in ``events.jsonl``; the message policy says a thing again when it changes):
the frame loop never waits for speech. espeak-ng speaks at 190 words per minute (its default is 175).
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any, Protocol

from stereo_classic.guide.messages import Event

__all__ = ["INSTALL_HINT", "EspeakEngine", "Pyttsx3Engine", "Speaker", "SpeechEngine", "find_engine"]

log = logging.getLogger("stereo_classic.guide")

#: What to install when no engine is found (one line).
INSTALL_HINT = ("no offline text-to-speech engine found: install espeak-ng (apt install espeak-ng, brew install "
                "espeak-ng) or pip install pyttsx3; continuing without speech")


class SpeechEngine(Protocol):
    name: str

    def say(self, text: str, *, interrupt: bool) -> bool | None: ...

    def to_wav(self, text: str, path: Path) -> None: ...

    def close(self) -> None: ...


class EspeakEngine:
    """The espeak-ng / espeak command-line program."""

    def __init__(self, program: str) -> None:
        self.program = program
        self.name = Path(program).name
        self._proc: subprocess.Popen | None = None

    def say(self, text: str, *, interrupt: bool) -> bool:
        """Start speaking ``text`` (the frame loop does not wait); False when busy and not ``interrupt``."""
        if self._proc is not None and self._proc.poll() is None:
            if not interrupt:
                return False
            self._proc.terminate()
            self._proc.wait()
        self._proc = subprocess.Popen([self.program, "-s", "190", "--", text], stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL)
        return True

    def to_wav(self, text: str, path: Path) -> None:
        subprocess.run([self.program, "-s", "190", "-w", os.fspath(path), "--", text], check=True,
                       stdout=subprocess.DEVNULL,
                       stderr=subprocess.PIPE, timeout=30)

    def close(self) -> None:
        if self._proc is not None and self._proc.poll() is None:
            self._proc.wait(timeout=30)


class Pyttsx3Engine:
    """The pyttsx3 package (blocking: each message is spoken before the next frame)."""

    def __init__(self, module: Any) -> None:
        self.engine = module.init()
        self.name = "pyttsx3"

    def say(self, text: str, *, interrupt: bool) -> bool:
        self.engine.say(text)
        self.engine.runAndWait()
        return True

    def to_wav(self, text: str, path: Path) -> None:
        self.engine.save_to_file(text, os.fspath(path))
        self.engine.runAndWait()

    def close(self) -> None:
        pass


def find_engine() -> SpeechEngine | None:
    """The first offline engine available here, or None."""
    for program in ("espeak-ng", "espeak"):
        path = shutil.which(program)
        if path:
            return EspeakEngine(path)
    try:
        import pyttsx3  # an optional extra, not a dependency
    except ImportError:
        return None
    try:
        return Pyttsx3Engine(pyttsx3)
    except Exception as exc:  # noqa: BLE001 - any driver failure means "no engine"
        log.debug("pyttsx3 present but unusable: %s", exc)
        return None


class Speaker:
    """Speak events aloud (``speak=True``) and/or write them to ``wav_dir`` as ``NNNNN_<frame>_<kind>.wav``.

    Parameters
    ----------
    speak : bool
    wav_dir : path or None
    engine : SpeechEngine, optional
        Default: :func:`find_engine`.

    Attributes
    ----------
    available : bool, an engine was found
    written : list of Path, the WAV files written
    """

    def __init__(self, *, speak: bool = False, wav_dir: str | os.PathLike[str] | None = None,
                 engine: SpeechEngine | None = None) -> None:
        self.speak = bool(speak)
        self.wav_dir = Path(wav_dir) if wav_dir is not None else None
        self.engine = engine if engine is not None else (find_engine() if (speak or wav_dir) else None)
        self.available = self.engine is not None
        self.written: list[Path] = []
        self._count = 0
        self._failed = False
        if (speak or wav_dir) and not self.available:
            log.warning(INSTALL_HINT)
        if self.wav_dir is not None:
            self.wav_dir.mkdir(parents=True, exist_ok=True)

    def __call__(self, event: Event) -> None:
        """Say one event; never raises."""
        if not self.available or self._failed:
            return
        try:
            if self.wav_dir is not None:
                name = re.sub(r"[^A-Za-z0-9._-]+", "_", f"{self._count:05d}_{event.frame}_{event.kind}") + ".wav"
                tmp = self.wav_dir / (name + ".part")
                self.engine.to_wav(event.text, tmp)
                os.replace(tmp, self.wav_dir / name)
                self.written.append(self.wav_dir / name)
            if self.speak:
                self.engine.say(event.text, interrupt=event.interrupt)
            self._count += 1
        except Exception as exc:  # noqa: BLE001 - speech must never end the run
            self._failed = True
            log.warning("speech stopped: %s (%s); the events are still written", exc, self.engine.name)

    def close(self) -> None:
        if self.engine is not None:
            try:
                self.engine.close()
            except Exception as exc:  # noqa: BLE001 - closing must not end the run either
                log.debug("closing %s: %s", self.engine.name, exc)
