"""Shared fixtures: where the real data and models are, and clean skips where they are not."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

# Property tests are deterministic: the same examples on every machine and run (no random seed, no example
# database replaying a local failure), so the test command cannot turn red by chance.
settings.register_profile("deterministic", derandomize=True, database=None)
settings.load_profile("deterministic")

REPO = Path(__file__).resolve().parents[1]


def _shared_dir(env: str, sub: str) -> Path | None:
    if os.environ.get(env):
        path = Path(os.environ[env])
    else:
        path = REPO.parent / "shared" / sub
    return path if path.is_dir() else None


SHARED_DATA = _shared_dir("STEREO_CLASSIC_DATA", "data")
SHARED_MODELS = _shared_dir("STEREO_CLASSIC_MODELS", "models")


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data`` (or ``$STEREO_CLASSIC_DATA``); the test is skipped where it is absent."""
    if SHARED_DATA is None:
        pytest.skip("real stereo data not present (../shared/data or STEREO_CLASSIC_DATA)")
    return SHARED_DATA


@pytest.fixture(scope="session")
def shared_models() -> Path:
    """``../shared/models`` (or ``$STEREO_CLASSIC_MODELS``); the test is skipped where it is absent."""
    if SHARED_MODELS is None:
        pytest.skip("detector models not present (../shared/models or STEREO_CLASSIC_MODELS)")
    return SHARED_MODELS


@pytest.fixture(scope="session")
def yolox_nano(shared_models: Path) -> Path:
    path = shared_models / "yolox_nano.onnx"
    if not path.is_file():
        pytest.skip(f"{path} not present")
    return path


@pytest.fixture
def sigint_delivered():
    """SIGINT raises KeyboardInterrupt during the test, as at a terminal. A job started in the background (``nohup``,
    ``&`` without job control, as some CI runners start their scripts) inherits SIGINT *ignored*, and the runner
    rightly leaves an ignored signal alone; a test of what Ctrl-C does must not depend on how it was started."""
    import signal

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
