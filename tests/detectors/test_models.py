"""resolve_model / download_model / `python -m detectors`: search order, checked downloads, offline errors."""

from __future__ import annotations

import functools
import hashlib
import http.server
import json
import os
import socket
import threading

import cv2
import numpy as np
import pytest

import detectors.models as models
from detectors import KNOWN_MODELS, ModelError, ModelNotFoundError, cache_dir, download_model, resolve_model
from detectors.cli import main
from detectors.models import KnownModel

PAYLOAD = b"tiny model bytes \x00\x01\x02" * 1000
PAYLOAD_SHA = hashlib.sha256(PAYLOAD).hexdigest()


@pytest.fixture()
def isolated(tmp_path, monkeypatch):
    """No STEREO_CLASSIC_MODELS, the cache in tmp_path/cache, KNOWN_MODELS restorable."""
    monkeypatch.delenv("STEREO_CLASSIC_MODELS", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(models, "KNOWN_MODELS", dict(KNOWN_MODELS))
    return tmp_path


@pytest.fixture()
def server(tmp_path):
    """HTTP server on 127.0.0.1 serving tmp_path/www; yields its base URL."""
    www = tmp_path / "www"
    www.mkdir()
    (www / "tiny.onnx").write_bytes(PAYLOAD)
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(www))
    handler.log_message = lambda *a, **k: None  # type: ignore[method-assign]
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()
    httpd.server_close()


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_known_models_have_checksums():
    known = KNOWN_MODELS["yolox_nano"]
    assert known.sha256 == "695e750a5d5754bb5a8d5325643b59282191a7e7a564e435a415fd3c578eab14"
    assert known.url.startswith("https://github.com/Megvii-BaseDetection/YOLOX/releases/")


def test_existing_path_is_returned(tmp_path):
    p = tmp_path / "m.onnx"
    p.write_bytes(b"x")
    assert resolve_model(p) == p and resolve_model(str(p)) == p


def test_missing_path(tmp_path):
    with pytest.raises(ModelNotFoundError, match="does not exist"):
        resolve_model(tmp_path / "missing.onnx")
    with pytest.raises(ModelNotFoundError, match="is a directory"):
        resolve_model(tmp_path)
    with pytest.raises(ValueError, match="`name_or_path`"):
        resolve_model(3)  # type: ignore[arg-type]


def test_env_folder_then_cache(isolated, monkeypatch):
    env_dir, cache = isolated / "env", cache_dir()
    env_dir.mkdir()
    cache.mkdir(parents=True)
    (cache / "foo.onnx").write_bytes(b"cache")
    assert resolve_model("foo") == cache / "foo.onnx"
    (env_dir / "foo.onnx").write_bytes(b"env")
    monkeypatch.setenv("STEREO_CLASSIC_MODELS", str(env_dir))
    assert resolve_model("foo") == env_dir / "foo.onnx"


def test_default_is_yolox_nano(yolox_nano, monkeypatch):
    monkeypatch.setenv("STEREO_CLASSIC_MODELS", str(yolox_nano.parent))
    assert resolve_model() == yolox_nano


def test_packaged_model_is_the_official_file():
    shipped = models.packaged_model("yolox_nano")
    assert shipped is not None and shipped.parent == models.DATA_DIR
    assert models.verify_sha256(shipped, KNOWN_MODELS["yolox_nano"].sha256)
    assert hashlib.sha256(shipped.read_bytes()).hexdigest() == (
        "695e750a5d5754bb5a8d5325643b59282191a7e7a564e435a415fd3c578eab14")
    licence = models.DATA_DIR / models.PACKAGED_MODELS["yolox_nano"][1]
    assert "Apache License" in licence.read_text() and "Version 2.0" in licence.read_text()
    assert models.packaged_model("nanodet_m_320") is None


def test_packaged_model_found_offline_before_the_cache(isolated, monkeypatch):
    shipped = models.packaged_model("yolox_nano")

    def no_network(*args, **kwargs):  # pragma: no cover - failing here is the test failing
        raise AssertionError("resolve_model must not download when the package holds the model")

    monkeypatch.setattr(models, "download_model", no_network)
    assert resolve_model() == shipped and resolve_model("yolox_nano") == shipped
    cache = cache_dir()
    cache.mkdir(parents=True)
    (cache / "yolox_nano.onnx").write_bytes(b"stale cache copy")
    assert resolve_model() == shipped  # the shipped file wins over the cache


def test_a_model_the_user_names_wins_over_the_packaged_one(isolated, monkeypatch, tmp_path):
    env_dir = tmp_path / "env"
    env_dir.mkdir()
    (env_dir / "yolox_nano.onnx").write_bytes(b"user's own")
    monkeypatch.setenv("STEREO_CLASSIC_MODELS", str(env_dir))
    assert resolve_model() == env_dir / "yolox_nano.onnx"
    own = tmp_path / "mine.onnx"
    own.write_bytes(b"x")
    assert resolve_model(own) == own and resolve_model(str(own)) == own


def test_unknown_name_one_line_error(isolated):
    with pytest.raises(ModelNotFoundError) as info:
        resolve_model("no_such_model")
    msg = str(info.value)
    assert "\n" not in msg and "STEREO_CLASSIC_MODELS" in msg and str(cache_dir()) in msg


def test_download_checked_atomic_and_cached(isolated, server):
    models.KNOWN_MODELS["tiny"] = KnownModel(url=f"{server}/tiny.onnx", sha256=PAYLOAD_SHA)
    path = resolve_model("tiny")
    assert path == cache_dir() / "tiny.onnx" and path.read_bytes() == PAYLOAD
    assert sorted(p.name for p in cache_dir().iterdir()) == ["tiny.onnx"]  # no temp file left
    models.KNOWN_MODELS["tiny"] = KnownModel(url=f"http://127.0.0.1:{_closed_port()}/tiny.onnx", sha256=PAYLOAD_SHA)
    assert resolve_model("tiny") == path  # from the cache, no network


def test_download_checksum_mismatch_leaves_nothing(isolated, server):
    models.KNOWN_MODELS["tiny"] = KnownModel(url=f"{server}/tiny.onnx", sha256="0" * 64)
    with pytest.raises(ModelError, match=r"has sha256 [0-9a-f]{64}, expected 0{64}; nothing was saved"):
        resolve_model("tiny")
    assert list(cache_dir().iterdir()) == []


def test_download_from_file_url(isolated, tmp_path):
    src = tmp_path / "src.onnx"
    src.write_bytes(PAYLOAD)
    out = download_model("tiny", url=src.as_uri(), sha256=PAYLOAD_SHA.upper(), dest_dir=tmp_path / "dest")
    assert out == tmp_path / "dest" / "tiny.onnx" and out.read_bytes() == PAYLOAD


@pytest.mark.parametrize("where", ["closed_port", "http_404"])
def test_offline_error_is_one_line(isolated, server, where):
    url = f"http://127.0.0.1:{_closed_port()}/tiny.onnx" if where == "closed_port" else f"{server}/absent.onnx"
    models.KNOWN_MODELS["tiny"] = KnownModel(url=url, sha256=PAYLOAD_SHA)
    with pytest.raises(ModelNotFoundError) as info:
        resolve_model("tiny")
    msg = str(info.value)
    assert "\n" not in msg and "download from" in msg and "STEREO_CLASSIC_MODELS" in msg and "tiny.onnx" in msg
    assert list(cache_dir().iterdir()) == []
    with pytest.raises(ModelNotFoundError, match="python -m detectors fetch tiny"):
        resolve_model("tiny", download=False)
    with pytest.raises(ModelNotFoundError, match="python -m detectors fetch tiny"):
        resolve_model("tiny")  # the failed download names the command too


def test_download_unknown_name():
    with pytest.raises(ValueError, match="no official download for model 'abc'"):
        download_model("abc")


class TestCli:
    def test_fetch(self, isolated, server, capsys):
        models.KNOWN_MODELS["tiny"] = KnownModel(url=f"{server}/tiny.onnx", sha256=PAYLOAD_SHA)
        assert main(["fetch", "tiny"]) == 0
        assert capsys.readouterr().out.strip() == str(cache_dir() / "tiny.onnx")
        assert main(["fetch", "tiny"]) == 0
        assert "already in the cache" in capsys.readouterr().err

    def test_fetch_failures(self, isolated, server, capsys):
        assert main(["fetch", "nothing_known"]) == 2
        assert "no official download" in capsys.readouterr().err
        models.KNOWN_MODELS["tiny"] = KnownModel(url=f"http://127.0.0.1:{_closed_port()}/t.onnx", sha256=PAYLOAD_SHA)
        assert main(["fetch", "tiny"]) == 1
        assert "STEREO_CLASSIC_MODELS" in capsys.readouterr().err
        models.KNOWN_MODELS["tiny"] = KnownModel(url=f"{server}/tiny.onnx", sha256="1" * 64)
        assert main(["fetch", "tiny"]) == 1
        assert "nothing was saved" in capsys.readouterr().err
        assert not (cache_dir() / "tiny.onnx").exists()

    def test_usage(self, capsys):
        assert main([]) == 2
        assert main(["--help"]) == 0
        assert main(["bogus"]) == 2

    def test_detect_json_lines(self, tmp_path, yolox_nano, shared_data, capsys):
        img = tmp_path / "selfie.png"
        cv2.imwrite(str(img), cv2.imread(str(shared_data / "oakd" / "selfie_left.png")))
        rc = main(["-q", "detect", str(img), str(tmp_path / "missing.png"), "--model", str(yolox_nano),
                   "--classes", "person", "--threads", "1"])
        assert rc == 1  # one image missing
        lines = capsys.readouterr().out.strip().splitlines()
        assert len(lines) == 1
        rec = json.loads(lines[0])
        assert [d["class_name"] for d in rec["detections"]] == ["person"]
        assert isinstance(rec["detections"][0]["confidence"], float)

    def test_detect_missing_model(self, tmp_path, capsys):
        img = tmp_path / "a.png"
        cv2.imwrite(str(img), np.zeros((10, 10, 3), np.uint8))
        assert main(["detect", str(img), "--model", str(tmp_path / "none.onnx")]) == 1
        assert "does not exist" in capsys.readouterr().err


def test_downloaded_model_mode_follows_the_umask(isolated, tmp_path):
    src = tmp_path / "src.onnx"
    src.write_bytes(PAYLOAD)
    old = os.umask(0o022)
    try:
        out = download_model("tiny", url=src.as_uri(), sha256=PAYLOAD_SHA, dest_dir=tmp_path / "dest")
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == 0o644  # like io.atomic_write, not mkstemp's 0o600
    assert [p.name for p in (tmp_path / "dest").iterdir()] == ["tiny.onnx"]


def _no_network(*args, **kwargs):  # pragma: no cover - reaching it is the failure
    raise AssertionError("fetch started the download before checking the cache folder")


def test_fetch_checks_the_cache_before_downloading(tmp_path, capsys, monkeypatch):
    (tmp_path / "cache").write_text("x")  # the cache's parent is a file
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(models, "download_model", _no_network)
    assert main(["fetch", "yolox_nano", "--force"]) == 1
    assert "is a file, not a folder" in capsys.readouterr().err


def test_the_wheel_declares_the_packaged_model_and_its_licence():
    import fnmatch
    import tomllib

    from tests.conftest import REPO

    patterns = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["detectors"]
    for file_name in models.PACKAGED_MODELS["yolox_nano"]:
        assert any(fnmatch.fnmatch(f"data/{file_name}", pat) for pat in patterns), file_name
        assert (REPO / "detectors" / "data" / file_name).is_file()
