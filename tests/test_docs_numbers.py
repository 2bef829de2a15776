"""Numbers the docs quote are rendered, not typed (issue 34): the README's results block and detectors.md's latency
table are what benchmarks/results/report.json holds, and fusion.md's KITTI distances are what the code gives now."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from tests.conftest import REPO

REPORT = REPO / "benchmarks" / "results" / "report.json"


def _flat(text: str) -> str:
    """Markdown with its line breaks (and the indent of list items) as single spaces."""
    return re.sub(r"\s+", " ", text)


def _assert_quoted(doc: str, expected: list[str], message: str) -> None:
    """Every line of ``expected`` is in docs/``doc`` (line breaks as spaces); else fail with ``message`` and them."""
    text = _flat((REPO / "docs" / doc).read_text(encoding="utf-8"))
    missing = [e for e in expected if e not in text]
    assert not missing, message + "\n" + "\n".join(missing)


@pytest.fixture(scope="module")
def report() -> dict:
    return json.loads(REPORT.read_text(encoding="utf-8"))


def test_readme_results_block_is_the_render_of_the_report(report):
    from benchmarks.render import readme_markdown

    block = readme_markdown(report).strip()
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert block in readme, "README's results block is not `python -m benchmarks.render benchmarks/results/report.json`"


def test_detector_latency_table_is_the_report(report):
    rows = report["detectors"]["rows"]
    assert rows, "the report has no detector latency rows"
    text = (REPO / "docs" / "detectors.md").read_text(encoding="utf-8")
    table = [line for line in text.splitlines() if re.match(r"\| \w+ \| \d+x\d+ \| \d \|", line)]
    expected = {f"| {r['model'].removesuffix('.onnx')} | {r['input_size'][0]}x{r['input_size'][1]} | {r['threads']} | "
                f"{r['preprocess_ms']:.2f} | {r['inference_ms']:.2f} | {r['postprocess_ms']:.2f} | "
                f"{r['total_ms']:.2f} |" for r in rows}
    assert set(table) == expected, ("docs/detectors.md's latency table is not the report's:\n"
                                    + "\n".join(sorted(expected)))


def _fmt(values) -> str:
    return " / ".join(f"{v:.2f}" for v in values)


def _errors(distance, reference) -> str:
    return ", ".join(f"{100 * (d / r - 1):+.1f} %" for d, r in zip(distance, reference))


def test_fusion_md_kitti_numbers_are_what_the_code_gives(shared_data, yolox_nano, report):
    import stereo_classic as sc
    from stereo_classic.datasets import load_scene
    from stereo_classic.fusion import localize, sparse_depth_reference

    kitti = load_scene(shared_data / "kitti_object_pair")
    with sc.Localizer(kitti.rig, yolox_nano, {"num_disparities": 128}) as loc:
        result = loc(kitti.left, kitti.right)
    objects = result.objects
    ref = sparse_depth_reference(kitti.gt_depth, objects.xyxy)
    ok = np.array(objects.ok)

    def alone(disparity, **overrides):
        return localize(result.detections, disparity, kitti.rig, rng=0, range_warning=False, **overrides).distance_m

    wide = alone(sc.compute_disparity(kitti.left, kitti.right, num_disparities=192))
    t = list(objects.status).index("beyond_range")  # the truncated car
    in_view = report["kitti_objects"]["objects"][0]["reference_m"]  # label 0: the truncated car (benchmarks.md)
    expected = [
        f"Reference {_fmt(ref)} m.",
        f"the others {_fmt(objects.distance_m[ok])} m: **{_errors(objects.distance_m[ok], ref[ok])}**.",
        f"(no checks, a `RangeWarning` about the truncated car): {_fmt(alone(result.disparity))} m, "
        f"{_errors(alone(result.disparity), ref)};",
        f"with 192 disparities the truncated car is in range: {wide[t]:.2f} m ({_errors(wide[t:t + 1], ref[t:t + 1])} "
        f"against this reference; against the median of its labelled box's LiDAR points that the left camera sees, "
        f"{in_view:.2f} m, {_errors(wide[t:t + 1], [in_view])},",
        f"`grow_density=0` (the paper's plain set): {_errors(alone(result.disparity, grow_density=0.0), ref)} (",
        f"`method=\"median\"`: {_errors(alone(result.disparity, method='median'), ref)} (",
    ]
    _assert_quoted("fusion.md", expected, "docs/fusion.md's KITTI numbers are not the code's; now:")


def test_fusion_md_pipeline_speed_is_the_report(report):
    """The speed paragraph's figures of the run in the repository: frames/s, the median and its stages, and the
    concurrent detector against the serial one at both sizes."""
    runs = {(tuple(p["size"]), bool(p.get("concurrent"))): p for p in report["pipeline"] if p.get("available")}
    kitti = runs[((1242, 375), False)]
    st = kitti["stages_median_ms"]
    commit = report["machine"]["git_commit"][:7]
    expected = [
        f"pipeline at **{kitti['fps']:.1f} frames/s** in the run at {commit}",
        f"({kitti['median_ms']:.1f} ms median: matcher {st['disparity']:.1f} ms, detector {st['detect']:.1f} ms, "
        f"fusion {st['localize']:.1f} ms, frame checks {st['checks']:.1f} ms:",
        f"({runs[((1242, 375), True)]['fps']:.1f} against {kitti['fps']:.1f} frames/s in the same run at {commit},",
        f"({runs[((640, 480), True)]['fps']:.1f} against {runs[((640, 480), False)]['fps']:.1f} at {commit},",
    ]
    _assert_quoted("fusion.md", expected, "docs/fusion.md's speed figures are not the report's; the report gives:")


def test_benchmarks_md_kitti_table_is_the_report(report):
    from benchmarks.kitti_objects import render_markdown

    rows = [line for line in render_markdown(report["kitti_objects"]).splitlines() if re.match(r"\| \d+ \|", line)]
    assert rows, "the report's KITTI objects table has no rows"
    text = (REPO / "docs" / "benchmarks.md").read_text(encoding="utf-8")
    missing = [row for row in rows if row not in text]
    assert not missing, "docs/benchmarks.md's KITTI table is not the report's rows:\n" + "\n".join(missing)
