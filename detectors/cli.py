"""``python -m detectors``: fetch a model into the cache, or run a detector on images.

``fetch`` knows the official files whose sha256 is recorded in :data:`detectors.models.KNOWN_MODELS` (today only
``yolox_nano``, which also ships with the package); any other exported ONNX detector is used by giving its path
to ``--model`` or putting ``NAME.onnx`` in ``$STEREO_CLASSIC_MODELS``. Every failure is one line ``error: ...``
on stderr. Exit codes: 0 success, 1 runtime failure (missing model, download failed, bad file), 2 usage error.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = ["main", "build_parser", "split_classes"]

log = logging.getLogger("detectors")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m detectors", description="ONNX object detectors (YOLOX, YOLOv5/8, NanoDet).")
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    verbosity.add_argument("-q", "--quiet", action="store_true", help="only errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    fetch = sub.add_parser("fetch", help="download a known model's official file into the user cache (sha256 "
                                         "checked); known: yolox_nano (also shipped with the package)")
    fetch.add_argument("name", nargs="?", default="yolox_nano", help="model name (default yolox_nano)")
    fetch.add_argument("--force", action="store_true", help="download again even when the cache holds a good copy")
    det = sub.add_parser("detect", help="detect objects in images; JSON lines on stdout (one per image)")
    det.add_argument("images", nargs="+", help="image files")
    det.add_argument("--model", default=None, help="model name or .onnx path (default yolox_nano)")
    det.add_argument("--conf", type=float, default=0.3, help="confidence threshold (default 0.3)")
    det.add_argument("--iou", type=float, default=0.45, help="NMS IoU threshold (default 0.45)")
    det.add_argument("--threads", type=int, default=None, help="onnxruntime threads")
    det.add_argument("--classes", nargs="+", default=None, metavar="LIST",
                     help="only these class names, comma-separated (e.g. car,person; spaces work too)")
    return parser


class _Formatter(logging.Formatter):
    """Messages as they are; an error is one line ``error: ...`` (the prefix every command of the project uses)."""

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        return f"error: {text}" if record.levelno >= logging.ERROR else text


class _StderrHandler(logging.StreamHandler):
    """To the ``sys.stderr`` of the moment (not the one of the first call: a test's captured stream closes)."""

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr
        super().emit(record)


def split_classes(values: Sequence[str] | None) -> list[str] | None:
    """Class names given as ``car,person`` or ``car person`` (or both): one flat list, None when none.

    >>> split_classes(["car,person", "bus"])
    ['car', 'person', 'bus']
    """
    if not values:
        return None
    return [name.strip() for value in values for name in value.split(",") if name.strip()] or None


def _configure_logging(verbose: int, quiet: bool) -> None:
    level = logging.ERROR if quiet else (logging.DEBUG if verbose >= 1 else logging.INFO)
    handler = _StderrHandler()
    handler.setFormatter(_Formatter("%(message)s"))
    root = logging.getLogger("detectors")
    root.handlers[:] = [handler]
    root.setLevel(level)
    root.propagate = False


def _unwritable(folder: Path) -> str:
    """Why a file cannot be written into ``folder`` (created if needed), or "" when it can."""
    base = next((p for p in (folder, *folder.parents) if p.exists()), Path("."))
    if not base.is_dir():
        return f"{base} is a file, not a folder"
    if not os.access(base, os.W_OK | os.X_OK):
        return f"no permission to write in {base}"
    return ""


def _fetch(args) -> int:
    from detectors.errors import ModelError
    from detectors.models import KNOWN_MODELS, cache_dir, download_model, verify_sha256

    known = KNOWN_MODELS.get(args.name)
    if known is None:
        log.error("no official download for model %r (known: %s); for another exported ONNX detector give its "
                  "path to --model, or put %s.onnx in a folder and set STEREO_CLASSIC_MODELS to that folder",
                  args.name, ", ".join(sorted(KNOWN_MODELS)), args.name)
        return 2
    target = cache_dir() / f"{args.name}.onnx"
    unwritable = _unwritable(target.parent)
    if unwritable:  # before the download, not after it
        log.error("cannot save %s into %s: %s; set XDG_CACHE_HOME to a writable folder", args.name, target.parent,
                  unwritable)
        return 1
    if target.is_file() and not args.force and verify_sha256(target, known.sha256):
        log.info("%s already in the cache, sha256 ok", target)
        print(target)
        return 0
    log.info("downloading %s from %s", args.name, known.url)
    try:
        path = download_model(args.name)
    except ModelError as exc:
        log.error("%s", exc)
        return 1
    except OSError as exc:
        reason = getattr(exc, "reason", exc)
        log.error("download of %s from %s failed (%s); put %s.onnx in %s or set STEREO_CLASSIC_MODELS",
                  args.name, known.url, reason, args.name, target.parent)
        return 1
    log.info("saved %s (sha256 ok, licence %s)", path, known.licence)
    print(path)
    return 0


def _detect(args) -> int:
    import cv2

    from detectors.imageio import read_image
    from detectors.onnx_detector import OnnxDetector

    try:
        detector = OnnxDetector(args.model or "yolox_nano", conf_threshold=args.conf, iou_threshold=args.iou,
                                threads=args.threads, classes=split_classes(args.classes))
    except (ValueError, FileNotFoundError) as exc:
        if args.verbose:
            log.exception("cannot open the detector")
        log.error("%s", exc)
        return 1 if isinstance(exc, FileNotFoundError) or type(exc).__name__ == "ModelError" else 2
    status = 0
    times: dict[str, list[float]] = {}
    images = args.images
    if sys.stderr.isatty() and len(images) > 1 and not args.quiet:
        from tqdm import tqdm

        images = tqdm(images, unit="image", file=sys.stderr)
    for path in images:
        try:
            image = read_image(path, cv2.IMREAD_COLOR)
        except (FileNotFoundError, ValueError) as exc:
            log.error("cannot read image: %s", exc)
            status = 1
            continue
        try:
            dets = detector.detect(image)
        except (ValueError, RuntimeError, MemoryError) as exc:  # ModelError: the model fails on real images
            if args.verbose:
                log.exception("detection failed")
            log.error("%s: %s", path, exc)
            status = 1
            if type(exc).__name__ == "ModelError":
                break  # the next images would fail the same way
            continue
        print(json.dumps({"image": path, "detections": dets.to_json(),
                          "timings_ms": {k: round(v, 2) for k, v in detector.last_timings_ms.items()}}))
        log.debug("%s: %d objects (%.1f ms)", path, len(dets), detector.last_timings_ms["total"])
        for k, v in detector.last_timings_ms.items():
            times.setdefault(k, []).append(v)
    if times:
        log.info("%d image(s), median ms: %s", len(times["total"]),
                 ", ".join(f"{k} {sorted(v)[len(v) // 2]:.1f}" for k, v in times.items()))
    return status


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    _configure_logging(args.verbose, args.quiet)
    if args.command == "fetch":
        return _fetch(args)
    if args.command == "detect":
        return _detect(args)
    parser.print_help(sys.stderr)
    return 2
