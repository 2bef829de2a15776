"""Where the guide puts the ground on the OAK-D scenes: one table row per scene.

Each pair goes once through the pipeline (64 disparities, YOLOX-nano when present, else depth only); then a
fresh :class:`stereo_classic.guide.Guide` sees it alone, as one frame (how ``guide`` treats a single pair),
and again as a still sequence of ``--frames`` frames at 10 fps (the ground tracker over frames: each frame's
RANSAC has its own seed). Reported: the first frame's camera height and pitch (or "ground unknown"), the up
direction its vertical lines give (:func:`~stereo_classic.guide.gravity.estimate_gravity`: pitch and roll, and its
angle to the ground plane), the range of heights over the sequence and the first frame's events; ``--seeds N``
adds the ground of the frame fitted alone (:func:`~stereo_classic.guide.fit_ground`, sampled and constrained as
the guide does) with RANSAC seeds 0 to N-1: how much one frame's estimate depends on the draw.
``--no-vertical-lines`` runs the guide without the measured up (``GuideParams.vertical_lines``). ``--save DIR``
writes the overlay and the birds-eye view of the first frame (``NAME_overlay.png``, ``NAME_birdseye.png``), as
``guide --save`` does.

    python -m benchmarks.guide_ground [--data DIR] [--frames N] [--seeds N] [--save DIR] [--no-vertical-lines]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2

from benchmarks.guide_cost import oakd_pipeline
from benchmarks.report import signed_zero_free
from stereo_classic.guide import Guide, fit_ground
from stereo_classic.guide.core import frame_points
from stereo_classic.guide.gravity import estimate_gravity
from stereo_classic.guide.render import draw_birdseye, draw_overlay
from stereo_classic.io import read_image

__all__ = ["main", "measure"]


def measure(data: Path, frames: int = 5, model: str | None = "yolox_nano", save: Path | None = None,
            seeds: int = 0, vertical_lines: bool = True) -> list[dict]:
    """One dict per ``*_left.png`` in ``data``: ``scene``, ``height_m``, ``pitch_deg``, ``roll_deg`` (None:
    ground unknown), ``gravity`` (the first frame's :class:`~stereo_classic.guide.gravity.Gravity` or None),
    ``angle_deg`` (between it and the ground's normal, or None), ``heights`` (the sequence's), ``events`` (texts
    of the first frame), ``seeded`` (``(height_m, pitch_deg)`` or None per seed)."""
    rig, lefts, loc = oakd_pipeline(data, model)
    rows = []
    with loc:
        for left in lefts:
            scene = left.name[: -len("_left.png")]
            result = loc(read_image(left), read_image(left.with_name(f"{scene}_right.png")))
            guide = Guide(vertical_lines=vertical_lines)
            seq = [guide.update(result, rig, i / 10.0, frame=scene) for i in range(max(1, frames))]
            first = seq[0]
            g, up = first.ground, first.gravity
            seeded = []
            if seeds:
                measured = result.disparity.disparity
                pts = frame_points(measured, rig, guide.params, result.left)  # as Guide
                fits = []
                for i in range(seeds):
                    gravity = estimate_gravity(result.left, rig, measured=measured, rng=i) if vertical_lines else None
                    fits.append(fit_ground(pts, rig.focal_px * rig.baseline_m, rng=i,
                                           gravity=None if gravity is None else gravity.up))
                seeded = [(f.height_m, f.pitch_deg) if f else None for f in fits]
            rows.append({"scene": scene, "seeded": seeded, "height_m": g.height_m if g else None,
                         "pitch_deg": g.pitch_deg if g else None, "roll_deg": g.roll_deg if g else None,
                         "gravity": up, "angle_deg": up.angle_deg(g.up) if g is not None and up is not None else None,
                         "heights": [f.ground.height_m if f.ground else None for f in seq],
                         "events": [e.text for e in first.events]})
            if save is not None:
                save.mkdir(parents=True, exist_ok=True)
                cv2.imwrite(str(save / f"{scene}_overlay.png"), draw_overlay(result.left, first, rig, guide.params))
                cv2.imwrite(str(save / f"{scene}_birdseye.png"), draw_birdseye(first, guide.params))
    return rows


def _fmt(v: float | None, spec: str) -> str:
    return "-" if v is None else signed_zero_free(format(v, spec), spec)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.guide_ground", description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared" / "data" / "oakd"),
                        help="the OAK-D folder (default: ../shared/data/oakd)")
    parser.add_argument("--frames", type=int, default=5, help="frames of the still sequence (default 5)")
    parser.add_argument("--seeds", type=int, default=0, help="also fit the frame alone with seeds 0..N-1")
    parser.add_argument("--save", default=None, help="folder for the first frame's overlay and birds-eye view")
    parser.add_argument("--no-vertical-lines", dest="vertical_lines", action="store_false",
                        help="the guide without the up direction measured from vertical lines")
    args = parser.parse_args(argv)
    data = Path(args.data)
    if not data.is_dir():
        print(f"error: --data {data} is not a folder", file=sys.stderr)
        return 2
    if args.frames < 1:
        print(f"error: --frames must be >= 1, got {args.frames}", file=sys.stderr)
        return 2
    rows = measure(data, args.frames, save=Path(args.save) if args.save else None, seeds=max(0, args.seeds),
                   vertical_lines=args.vertical_lines)
    print("| scene | height m | pitch deg | roll deg | vertical lines: pitch / roll deg (lines) | angle to the ground "
          "deg | heights over the sequence | events (first frame) |"
          + (f" seeds 0-{args.seeds - 1}: heights (fitted) |" if args.seeds > 0 else ""))
    print("|---|---|---|---|---|---|---|---|" + ("---|" if args.seeds > 0 else ""))
    for r in rows:
        hs = [h for h in r["heights"] if h is not None]
        seq = f"{min(hs):.2f}-{max(hs):.2f} ({len(hs)}/{len(r['heights'])})" if hs else "ground unknown"
        first = "ground unknown" if r["height_m"] is None else _fmt(r["height_m"], ".2f")
        up = r["gravity"]
        lines = "-" if up is None else f"{up.pitch_deg:.1f} / {up.roll_deg:.1f} ({up.lines})"
        line = (f"| {r['scene']} | {first} | {_fmt(r['pitch_deg'], '.1f')} | {_fmt(r['roll_deg'], '.1f')} | {lines} | "
                f"{_fmt(r['angle_deg'], '.1f')} | {seq} | {'; '.join(r['events']) or '-'} |")
        if r["seeded"]:
            fitted = [hp[0] for hp in r["seeded"] if hp is not None]
            line += (f" {min(fitted):.2f}-{max(fitted):.2f} ({len(fitted)}/{len(r['seeded'])}) |" if fitted
                     else f" none (0/{len(r['seeded'])}) |")
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
