"""benchmarks.kernel_profile: the perf map of numba's functions, the report's parsing and the table; the whole probe
where Linux perf can sample this process (skipped, and said why, where it cannot)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import kernel_profile as kp

_REPORT = """# To display the perf.data header info, please use --header/--header-only options.
#
# Samples: 48K of event 'cpu-clock:pppH'
#
#  Samples  Symbol
# ........  ..........................
#
     15253  [.] rowpass.three_path_stripe
      7569  [.] cost.row_cost
       576  [k] exc_page_fault
         3  [.] 0x00007f894a5af873
"""


def test_parse_report_reads_the_sample_counts():
    assert kp.parse_report(_REPORT) == {"rowpass.three_path_stripe": 15253, "cost.row_cost": 7569,
                                        "[k] exc_page_fault": 576, "0x00007f894a5af873": 3}


def test_summarize_per_frame_pixel_and_disparity():
    rows = kp.summarize({"a": 3000, "b": 1000, "c": 4}, frames=10, rate=1000, pixels=1000, disparities=50, top=2)
    assert [r["function"] for r in rows] == ["a", "b", "other", "total"]
    a = rows[0]
    assert a["ms_per_frame"] == pytest.approx(300.0)  # 3000 samples at 1 kHz over 10 frames
    assert a["ns_per_pixel"] == pytest.approx(300e6 / 1000)
    assert a["ns_per_pixel_disparity"] == pytest.approx(300e6 / 1000 / 50)
    assert rows[2]["samples"] == 4 and rows[3]["samples"] == 4004
    assert sum(r["share"] for r in rows[:3]) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="frames"):
        kp.summarize({"a": 1}, frames=0, rate=1000, pixels=1, disparities=1)


def test_perf_map_spans_each_symbol_to_the_next(tmp_path):
    path = kp.write_perf_map({0x2000: "b", 0x1000: "a"}, pid=123, directory=tmp_path)
    assert path.name == "perf-123.map"
    assert path.read_text().splitlines() == ["1000 1000 a", "2000 100000 b"]


def test_readable_names_of_numba_symbols():
    mangled = "_ZN14stereo_classic8matching8_kernels4cost8row_costB3v29B52c8tJTIeFIjxB2IKSgE5ArrayIsLi1E1C7mutable"
    assert kp.readable_name(mangled) == "cost.row_cost"
    assert kp.readable_name("cfunc." + mangled) == "cfunc.cost.row_cost"
    assert kp.readable_name("_ZN7cpython14stereo_classic8matching8_kernels4cost8row_costB3v29E") == "cpython.cost.row_cost"
    assert kp.readable_name("NRT_incref") == "NRT_incref"


def test_numba_symbols_name_the_matchers_kernels():
    from stereo_classic.matching import StereoMatcher

    rng = np.random.default_rng(3)
    left = rng.integers(0, 256, (40, 120), dtype=np.uint8)
    StereoMatcher(num_disparities=64, threads=1).compute(left, np.roll(left, -4, axis=1))
    symbols = kp.numba_symbols()
    names = set(symbols.values())
    assert {"rowpass.three_path_stripe", "cost.row_cost", "select.select_row"} <= names
    assert all(address > 0 for address in symbols)


def test_the_probe_names_where_the_time_went():
    why = kp.perf_available()
    if why is not None:
        pytest.skip(f"perf cannot sample here: {why}")
    from stereo_classic.matching import StereoMatcher

    rng = np.random.default_rng(4)
    left = rng.integers(0, 256, (120, 320), dtype=np.uint8)
    right = np.roll(left, -4, axis=1)
    matcher = StereoMatcher(num_disparities=64, threads=1)
    samples, seconds = kp.profile(lambda: matcher.compute(left, right), 30, rate=2000)
    assert seconds > 0
    assert samples.get("rowpass.three_path_stripe", 0) > 0  # the aggregation, named through the map
    top3 = sorted(samples, key=samples.get, reverse=True)[:3]
    assert "rowpass.three_path_stripe" in top3, samples


def test_a_perf_that_cannot_sample_is_said_and_the_probe_exits_1(tmp_path, monkeypatch, capsys):
    fake = tmp_path / "perf"
    fake.write_text("#!/bin/sh\necho 'Access to performance monitoring and observability operations is limited.' >&2\n"
                    "exit 255\n")
    fake.chmod(0o755)
    monkeypatch.setattr(kp.shutil, "which", lambda name: str(fake) if name == "perf" else None)
    why = kp.perf_available()
    assert why == "`perf record` failed: Access to performance monitoring and observability operations is limited."
    with pytest.raises(RuntimeError, match="performance monitoring"):
        kp.profile(lambda: None, 1)
    assert kp.main(["--frames", "1"]) == 1
    assert capsys.readouterr().err.startswith("error: `perf record` failed: Access")
