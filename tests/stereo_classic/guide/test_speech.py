"""Speech: WAV files through an engine, one hint without an engine, never a failed run."""

from __future__ import annotations

import logging
import wave

from stereo_classic.guide import Event
from stereo_classic.guide import speech as speech_mod
from stereo_classic.guide.speech import INSTALL_HINT, Speaker


def _event(text="person, 12 o'clock, 2.0 metres", priority="warning"):
    return Event("frame_1", 0.1, "object", "person", 1, 2.0, 2.0, 12, 0.0, None, None, priority, text,
                 interrupt=priority == "danger")


class ToneEngine:
    """A stand-in engine: a short silent WAV per message; records what it was asked to say."""

    name = "tone"

    def __init__(self):
        self.said = []

    def say(self, text, *, interrupt):
        self.said.append((text, interrupt))

    def to_wav(self, text, path):
        with wave.open(str(path), "wb") as w:
            w.setnchannels(1)
            w.setsampwidth(2)
            w.setframerate(8000)
            w.writeframes(b"\0\0" * 800)

    def close(self):
        pass


class BrokenEngine(ToneEngine):
    def say(self, text, *, interrupt):
        raise RuntimeError("audio device busy")


def test_wav_per_message_and_interrupts(tmp_path):
    engine = ToneEngine()
    speaker = Speaker(speak=True, wav_dir=tmp_path / "wav", engine=engine)
    speaker(_event())
    speaker(_event("drop-off, 12 o'clock, 0.8 metres", "danger"))
    names = sorted(p.name for p in (tmp_path / "wav").iterdir())
    assert names == ["00000_frame_1_object.wav", "00001_frame_1_object.wav"]
    assert [i for _, i in engine.said] == [False, True]
    with wave.open(str(tmp_path / "wav" / names[0])) as w:
        assert w.getnframes() == 800


def test_no_engine_one_hint_no_failure(tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(speech_mod, "find_engine", lambda: None)
    with caplog.at_level(logging.WARNING):
        speaker = Speaker(speak=True, wav_dir=tmp_path)
        speaker(_event())
        speaker(_event())
    assert not speaker.available and speaker.written == []
    assert [r.getMessage() for r in caplog.records] == [INSTALL_HINT]


def test_engine_failure_is_logged_once_and_speech_stops(caplog):
    speaker = Speaker(speak=True, engine=BrokenEngine())
    with caplog.at_level(logging.WARNING):
        speaker(_event())
        speaker(_event())
    assert sum("speech stopped" in r.getMessage() for r in caplog.records) == 1
