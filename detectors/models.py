"""Finding a model file: explicit path, ``$STEREO_CLASSIC_MODELS``, the packaged model, the user cache, or a checked
download.

The default detector, YOLOX-nano (Apache-2.0, Megvii), ships with this package (``detectors/data``), so the
default works offline; :data:`PACKAGED_MODELS` lists the files shipped.

>>> packaged_model("yolox_nano").name
'yolox_nano.onnx'
"""

from __future__ import annotations

import hashlib
import os
import secrets
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from detectors.errors import ModelError, ModelNotFoundError

__all__ = ["DEFAULT_MODEL", "KNOWN_MODELS", "MODELS_ENV", "PACKAGED_MODELS", "KnownModel", "cache_dir", "download_model",
           "packaged_model", "resolve_model", "verify_sha256"]

MODELS_ENV = "STEREO_CLASSIC_MODELS"
DEFAULT_MODEL = "yolox_nano"


@dataclass(frozen=True)
class KnownModel:
    """A model with an official download: its URL, sha256 and licence."""

    url: str
    sha256: str
    licence: str = ""


KNOWN_MODELS: dict[str, KnownModel] = {
    "yolox_nano": KnownModel(
        url="https://github.com/Megvii-BaseDetection/YOLOX/releases/download/0.1.1rc0/yolox_nano.onnx",
        sha256="695e750a5d5754bb5a8d5325643b59282191a7e7a564e435a415fd3c578eab14",
        licence="Apache-2.0 (Megvii YOLOX)",
    ),
}
"""Models :func:`resolve_model` may download. Only files whose sha256 is known are listed."""

#: Folder of the model files shipped with the package.
DATA_DIR = Path(__file__).resolve().parent / "data"
#: Models shipped with the package: name -> (file in :data:`DATA_DIR`, licence file there).
PACKAGED_MODELS: dict[str, tuple[str, str]] = {
    "yolox_nano": ("yolox_nano.onnx", "LICENSE_yolox_nano_Apache-2.0.txt"),
}


def packaged_model(name: str = DEFAULT_MODEL) -> Path | None:
    """The shipped file of model ``name``, or None when the package does not hold it."""
    entry = PACKAGED_MODELS.get(name)
    if entry is None:
        return None
    path = DATA_DIR / entry[0]
    return path if path.is_file() else None


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/stereo_classic/models`` (default ``~/.cache/stereo_classic/models``)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "stereo_classic" / "models"


def _looks_like_path(text: str) -> bool:
    return os.sep in text or (os.altsep is not None and os.altsep in text) or text.lower().endswith(".onnx")


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def resolve_model(name_or_path: str | os.PathLike | None = None, *, download: bool = True) -> Path:
    """Where the model file is.

    Order: an existing path; ``$STEREO_CLASSIC_MODELS/<name>.onnx`` (a folder the user chose wins over what
    ships); the file shipped with the package (:data:`PACKAGED_MODELS`: ``yolox_nano``, the default); the user
    cache (:func:`cache_dir`) ``<name>.onnx``; a download of the official file (only names in
    :data:`KNOWN_MODELS`, sha256 checked) into the cache.

    Parameters
    ----------
    name_or_path : str or path, optional
        A file path or a model name (default ``"yolox_nano"``).
    download : bool
        Allow the download step.

    Raises
    ------
    ModelNotFoundError
        One line saying where to put the file or which variable to set.
    ModelError
        The download did not match its sha256 (nothing is kept).
    """
    if name_or_path is None:
        name_or_path = DEFAULT_MODEL
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise ValueError(f"`name_or_path` must be a model name or a path, got {type(name_or_path).__name__}")
    text = os.fspath(name_or_path)
    if not text:
        raise ValueError("`name_or_path` must not be empty")
    path = Path(text).expanduser()
    if path.is_file():
        return path
    if isinstance(name_or_path, os.PathLike) or _looks_like_path(text):
        if path.is_dir():
            raise ModelNotFoundError(f"model path {path} is a directory, expected an .onnx file")
        raise ModelNotFoundError(f"model file {path} does not exist")
    name = text
    candidates = []
    env = os.environ.get(MODELS_ENV)
    if env:
        candidates.append(Path(env).expanduser() / f"{name}.onnx")
    shipped = packaged_model(name)
    if shipped is not None:
        candidates.append(shipped)
    cached = cache_dir() / f"{name}.onnx"
    candidates.append(cached)
    for c in candidates:
        if c.is_file():
            return c
    where = f"put {name}.onnx in {cached.parent} or set {MODELS_ENV} to the folder holding it"
    known = KNOWN_MODELS.get(name)
    if known is not None:
        where += f", or run `python -m detectors fetch {name}` where the network is reachable"
    if known is None:
        raise ModelNotFoundError(f"model {name!r} not found: {where} (no official download for this name; "
                                 f"known: {', '.join(sorted(KNOWN_MODELS))})")
    if not download:
        raise ModelNotFoundError(f"model {name!r} not found: {where}")
    try:
        return download_model(name)
    except OSError as exc:
        raise ModelNotFoundError(f"model {name!r} not found and the download from {known.url} failed "
                                 f"({_reason(exc)}): {where}") from None


def _reason(exc: BaseException) -> str:
    if isinstance(exc, urllib.error.URLError) and not isinstance(exc, urllib.error.HTTPError):
        return f"{exc.reason}".replace("\n", " ")
    return f"{exc}".replace("\n", " ")


def download_model(name: str, *, url: str | None = None, sha256: str | None = None,
                   dest_dir: str | os.PathLike | None = None, timeout: float = 30.0) -> Path:
    """Download ``<name>.onnx`` into ``dest_dir`` (default :func:`cache_dir`), checking its sha256.

    The file is written to a temporary name in the same folder and renamed into place only after
    the checksum matched, so a failed or wrong download leaves nothing behind. ``url``/``sha256``
    default to :data:`KNOWN_MODELS`. Raises ``OSError`` (``urllib.error.URLError``) when the
    download fails and :class:`ModelError` on a checksum mismatch.
    """
    known = KNOWN_MODELS.get(name)
    if url is None or sha256 is None:
        if known is None:
            raise ValueError(f"no official download for model {name!r}; known: {', '.join(sorted(KNOWN_MODELS))}")
        url = url or known.url
        sha256 = sha256 or known.sha256
    sha256 = sha256.lower()
    folder = Path(dest_dir) if dest_dir is not None else cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / f"{name}.onnx"
    # same behaviour as stereo_classic.io.atomic_write (detectors is a leaf package and must not import
    # stereo_classic): mode 0o666 so that the umask decides, flushed and fsynced, removed on any failure
    tmp = folder / f".{name}.{secrets.token_hex(6)}.part"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        out = os.fdopen(fd, "wb")
    except BaseException:
        os.close(fd)
        tmp.unlink(missing_ok=True)
        raise
    try:
        h = hashlib.sha256()
        with out, urllib.request.urlopen(url, timeout=timeout) as resp:
            for chunk in iter(lambda: resp.read(1 << 20), b""):
                h.update(chunk)
                out.write(chunk)
            out.flush()
            os.fsync(out.fileno())
        got = h.hexdigest()
        if got != sha256:
            raise ModelError(f"download of {name} from {url} has sha256 {got}, expected {sha256}; nothing was saved")
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return target


def verify_sha256(path: str | os.PathLike, sha256: str) -> bool:
    """True when the file's sha256 is ``sha256``."""
    return _sha256(Path(path)) == sha256.lower()
