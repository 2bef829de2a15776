"""``run --save mcap``: one recording of the results, every frame's messages in order, stamped like the input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap_ros2.writer", reason="the bag extra (mcap, mcap-ros2-support) is not installed")

import calib  # noqa: E402
from stereo_classic.cli.main import main  # noqa: E402
from stereo_classic.io import read_image, read_pfm  # noqa: E402
from tests.helpers import ros_bags  # noqa: E402
from tests.helpers.ros_bags import LEFT, RIGHT  # noqa: E402

T0 = 1_700_000_000 * 1_000_000_000


def read_ros2_messages(path: Path) -> list:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(path, "rb") as f:
        return list(make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())


def _kitti_pair(shared_data: Path):
    """(left, right, rig) of the shared KITTI pair; the test is skipped where it is absent."""
    folder = shared_data / "kitti_object_pair"
    if not folder.is_dir():
        pytest.skip("kitti_object_pair not in the shared data")
    return read_image(folder / "left.png"), read_image(folder / "right.png"), calib.load_rig(folder / "calib.txt")


def test_save_mcap_holds_every_frame_in_order(shared_data: Path, tmp_path):
    left, right, rig = _kitti_pair(shared_data)
    stamps = [T0, T0 + 50_000_000, T0 + 100_000_000]
    bag = ros_bags.stereo_bag(tmp_path / "in.mcap", left, right, rig, stamps)
    out = tmp_path / "out"
    assert main(["run", "-q", "--bag", str(bag), "--left-topic", LEFT, "--right-topic", RIGHT,
                 "--save", "json,pfm,mcap", "-o", str(out)]) == 0
    records = [json.loads(line) for line in (out / "objects.jsonl").read_text().splitlines()]
    messages = read_ros2_messages(out / "results.mcap")
    assert [m.channel.topic for m in messages] == [
        "/stereo_classic/disparity", "/stereo_classic/objects/markers", "/stereo_classic/objects"] * 3
    assert [m.message.log_time for m in messages] == [s for s in stamps for _ in range(3)]
    for k, record in enumerate(records):
        disp_msg, markers, objects = (m.decoded_message for m in messages[3 * k: 3 * k + 3])
        assert (disp_msg.header.stamp.sec, disp_msg.header.stamp.nanosec) == divmod(stamps[k], 1_000_000_000)
        assert disp_msg.header.frame_id == "left_camera"
        assert json.loads(objects.data) == record
        image = np.frombuffer(disp_msg.image.data, dtype="<f4").reshape(disp_msg.image.height, disp_msg.image.width)
        pfm = read_pfm(out / f"{record['frame']}_disparity.pfm")
        measured = image >= disp_msg.min_disparity  # unknown (NaN) -> below the valid range
        assert 0.3 < measured.mean() < 1.0 and np.all(image[~measured] == disp_msg.min_disparity - 1)
        # the PFM holds the measured pixels only (NaN elsewhere): the same pixels, the same values
        assert np.array_equal(measured, np.isfinite(pfm))
        np.testing.assert_array_equal(image[measured], pfm[measured])
        assert disp_msg.f == pytest.approx(rig.focal_px) and disp_msg.t == pytest.approx(rig.baseline_m)
        cubes = [m for m in markers.markers if m.ns == "objects" and m.type == 1]
        assert markers.markers[0].action == 3  # DELETEALL: the previous frame's boxes go
        with_distance = [o for o in record["objects"] if o["distance_m"] is not None]
        assert len(cubes) == len(with_distance) >= 3
        for cube in cubes:
            o = record["objects"][cube.id]
            assert cube.pose.position.z - cube.scale.z / 2 == pytest.approx(o["distance_m"], abs=5e-4)
            assert cube.text == f"{o['label']} {o['distance_m']:.1f} m"


def test_save_mcap_refuses_resume(tmp_path, capsys):
    code = main(["run", "--save", "mcap", "--resume", "-o", str(tmp_path / "o"), "--model", "none"])
    assert code == 2 and "cannot be resumed" in capsys.readouterr().err


def test_guide_save_mcap_holds_the_events(shared_data: Path, tmp_path):
    left, right, rig = _kitti_pair(shared_data)
    bag = ros_bags.stereo_bag(tmp_path / "in.mcap", left, right, rig, [T0, T0 + 100_000_000])
    out = tmp_path / "guide"
    assert main(["guide", "-q", "--bag", str(bag), "--left-topic", LEFT, "--right-topic", RIGHT, "--save", "mcap",
                 "-o", str(out)]) == 0
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    events = [e for e in events if e["kind"] != "haptics"]
    assert events  # the KITTI frame says at least that the ground is not seen
    messages = read_ros2_messages(out / "results.mcap")
    said = [json.loads(m.decoded_message.data) for m in messages if m.channel.topic == "/stereo_classic/guide/events"]
    assert said == events
    assert [m.message.log_time for m in messages if m.channel.topic == "/stereo_classic/disparity"] == [
        T0, T0 + 100_000_000]
