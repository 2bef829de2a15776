"""``run --bag``: a real MCAP recording of the KITTI pair gives what ``run`` gives on the image files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap_ros2.writer", reason="the bag extra (mcap, mcap-ros2-support) is not installed")

import calib  # noqa: E402
from stereo_classic.cli.main import main  # noqa: E402
from stereo_classic.ros.bag import BagSource  # noqa: E402
from tests.helpers import ros_bags  # noqa: E402
from tests.helpers.ros_bags import LEFT, RIGHT  # noqa: E402

T0 = 1_700_000_000 * 1_000_000_000
STAMPS = [T0, T0 + 100_000_000, T0 + 200_000_000]


def _run_bag(bag: Path, out: Path, *extra: str, quiet: bool = True) -> int:
    return main(["run", *(["-q"] if quiet else []), "--bag", str(bag), "--left-topic", LEFT, "--right-topic", RIGHT,
                 "--save", "json", "-o", str(out), *extra])


def test_run_bag_equals_run_on_files(kitti, files_objects, tmp_path, capsys):
    _, left, right, rig = kitti
    lonely = ros_bags.image_msg(right, T0 + 150_000_000)  # a right image whose left was dropped
    bag = ros_bags.stereo_bag(tmp_path / "k.mcap", left, right, rig, STAMPS, left_encoding="rgb8",
                              extra=[(RIGHT, "sensor_msgs/msg/Image", lonely, T0 + 150_000_000)])
    capsys.readouterr()
    assert _run_bag(bag, tmp_path / "out", "--no-progress", quiet=False) == 0
    err = capsys.readouterr().err  # the summary line names it
    assert ("3 frame(s), " in err and "; 1 image message(s) without a partner not used: /stereo/right/image_rect: 1 "
            "(1700000000.150000000)" in err), err
    records = [json.loads(line) for line in (tmp_path / "out" / "objects.jsonl").read_text().splitlines()]
    assert [r["frame"] for r in records] == ["1700000000.000000000", "1700000000.100000000",
                                            "1700000000.200000000"]
    assert [r["source"]["time_s"] for r in records] == [0.0, 0.1, 0.2]
    for r in records:
        assert r["objects"] == files_objects
        assert r["rig"]["baseline_m"] == pytest.approx(rig.baseline_m, abs=1e-6)


def test_compressed_bag_and_tolerance(kitti, files_objects, tmp_path):
    _, left, right, rig = kitti
    bag = ros_bags.stereo_bag(tmp_path / "c.mcap", left, right, rig, [T0], compressed=True)
    assert main(["run", "-q", "--bag", str(bag), "--left-topic", LEFT + "/compressed", "--right-topic",
                 RIGHT + "/compressed", "--save", "json", "-o", str(tmp_path / "out")]) == 0
    assert json.loads((tmp_path / "out" / "1700000000.000000000_objects.json").read_text())["objects"] \
        == files_objects


def test_pairing_by_nearest_stamp(kitti, tmp_path):
    _, left, right, rig = kitti
    small_l, small_r = left[:64, :256], right[:64, :256]
    msgs = [(LEFT, "sensor_msgs/msg/Image", ros_bags.image_msg(small_l, ns), ns) for ns in (0, 10_000_000)]
    msgs += [(RIGHT, "sensor_msgs/msg/Image", ros_bags.image_msg(small_r, ns), ns) for ns in (2_000_000, 30_000_000)]
    bag = ros_bags.write_bag(tmp_path / "n.mcap", msgs)
    wide = calib.RectifiedRig(focal_px=700.0, cx_left=128.0, cx_right=128.0, cy=32.0, baseline_m=0.5,
                              image_size=(256, 64))
    for tolerance in (0.0, 0.0001):  # no equal stamps: nothing is matched silently
        with pytest.raises(ValueError, match="no left message"):
            BagSource(bag, LEFT, RIGHT, rig=wide, tolerance_s=tolerance)
    near = BagSource(bag, LEFT, RIGHT, rig=wide, tolerance_s=0.005)
    assert near.names == ["0.000000000"]
    assert near.unpaired == {LEFT: ["0.010000000"], RIGHT: ["0.030000000"]}
    frame = next(near.frames())
    assert np.array_equal(frame.left, small_l) and np.array_equal(frame.right, small_r)


def _one_error_line(err: str) -> str:
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


def _tiny(tmp_path: Path, name: str, left_msg: dict, right_msg: dict, infos: bool = True,
          size: tuple[int, int] = (256, 64)) -> Path:
    rig = calib.RectifiedRig(focal_px=700.0, cx_left=128.0, cx_right=128.0, cy=32.0, baseline_m=0.5, image_size=size)
    msgs = [(LEFT, "sensor_msgs/msg/Image", left_msg, 10), (RIGHT, "sensor_msgs/msg/Image", right_msg, 11)]
    if infos:
        msgs += [(ros_bags.LEFT_INFO, "sensor_msgs/msg/CameraInfo", ros_bags.info_msg(rig.P_left, size, 0), 1),
                 (ros_bags.RIGHT_INFO, "sensor_msgs/msg/CameraInfo", ros_bags.info_msg(rig.P_right, size, 0), 2)]
    return ros_bags.write_bag(tmp_path / name, sorted(msgs, key=lambda m: m[3]))


GREY = np.tile(np.arange(256, dtype=np.uint8), (64, 1))


@pytest.mark.parametrize("case, expected", [
    ("no_info", "has no CameraInfo on /stereo/left/camera_info and /stereo/right/camera_info and no --calib"),
    ("missing_topic", "--right-topic /stereo/right/image_rect: no such topic in bad.mcap; its topics: "),
    ("encoding", "image encoding '32FC1' cannot be converted"),
    ("sizes", "the left image is 256x64, the right one 128x64"),
    ("info_size", "the images are 256x64 but the CameraInfo says 320x64"),
])
def test_bad_input_is_one_line(case, expected, tmp_path, capsys):
    left = ros_bags.image_msg(GREY, 0, "mono8")
    right = ros_bags.image_msg(GREY, 0, "mono8")
    infos, size = True, (256, 64)
    if case == "no_info":
        infos = False
    elif case == "encoding":
        left = {**left, "encoding": "32FC1", "step": 1024, "data": np.zeros((64, 256), np.float32).tobytes()}
    elif case == "sizes":
        right = ros_bags.image_msg(GREY[:, :128], 0, "mono8")
    elif case == "info_size":
        size = (320, 64)
    bag = _tiny(tmp_path, "bad.mcap", left, right, infos, size)
    if case == "missing_topic":  # a bag with only the left camera
        bag = ros_bags.write_bag(tmp_path / "bad.mcap", [(LEFT, "sensor_msgs/msg/Image", left, 10)])
    capsys.readouterr()
    code = _run_bag(bag, tmp_path / "out", "--model", "none")
    line = _one_error_line(capsys.readouterr().err)
    assert code != 0 and expected in line, line
    if case == "missing_topic":
        assert "/stereo/left/image_rect (sensor_msgs/msg/Image)" in line
    assert not (tmp_path / "out").exists()  # bad input fails before the output folder is made
