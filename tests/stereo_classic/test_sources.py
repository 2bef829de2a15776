"""stereo_classic.sources: pairs, scenes and side-by-side video as frames."""

from __future__ import annotations

import numpy as np
import pytest


def test_expand_pairs_and_names(tmp_path):
    from stereo_classic.sources import PairSource, SourceError, expand_pairs

    for i in (2, 0, 1):
        (tmp_path / f"a{i}_L.png").write_bytes(b"x")
        (tmp_path / f"a{i}_R.png").write_bytes(b"x")
    pairs = expand_pairs([str(tmp_path / "*_L.png")], [str(tmp_path / "*_R.png")])
    assert [p[0].name for p in pairs] == ["a0_L.png", "a1_L.png", "a2_L.png"]
    assert PairSource(pairs).names == ["a0_L", "a1_L", "a2_L"]
    assert PairSource([(tmp_path / "a0_L.png", tmp_path / "a0_R.png")] * 2).names == ["a0_L", "a0_L_1"]
    with pytest.raises(SourceError, match="matches no file"):
        expand_pairs([str(tmp_path / "*.jpg")], [str(tmp_path / "*_R.png")])
    with pytest.raises(SourceError, match="paired in order"):
        expand_pairs([str(tmp_path / "*_L.png")], [str(tmp_path / "a0_R.png")])
    with pytest.raises(FileNotFoundError, match="nope"):
        expand_pairs([str(tmp_path / "nope.png")], [str(tmp_path / "a0_R.png")])


class _Capture:
    def __init__(self, frames, opened=True, count=0):
        self.frames, self.opened, self.count = list(frames), opened, count

    def isOpened(self):  # noqa: N802
        return self.opened

    def read(self):
        return (True, self.frames.pop(0)) if self.frames else (False, None)

    def get(self, prop):
        return float(self.count)

    def release(self):
        self.frames = []


def test_side_by_side_source_splits_and_stops():
    from stereo_classic.sources import SideBySideSource, SourceError

    frame = np.zeros((4, 6, 3), np.uint8)
    frame[:, 3:] = 255
    src = SideBySideSource(0, capture_factory=lambda _: _Capture([frame, frame]))
    got = list(src.frames())
    assert len(got) == 2 and src.stopped_early and src.frames_read == 2
    assert got[0].left.shape == (4, 3, 3) and got[0].left.max() == 0 and got[0].right.min() == 255
    src = SideBySideSource(0, max_frames=1, capture_factory=lambda _: _Capture([frame, frame]))
    assert len(list(src.frames())) == 1 and not src.stopped_early
    with pytest.raises(SourceError, match="cannot open camera 3"):
        SideBySideSource(3, capture_factory=lambda _: _Capture([], opened=False))
    odd = SideBySideSource(0, capture_factory=lambda _: _Capture([np.zeros((4, 5, 3), np.uint8)]))
    with pytest.raises(SourceError, match="even width"):
        list(odd.frames())


def test_scene_source_dataset_folder(shared_data):
    from stereo_classic.sources import SceneSource, SourceError

    src = SceneSource.from_folder(shared_data / "oakd")
    assert len(src) == 12 and len(set(src.names)) == 12
    frames = list(src.frames(lambda name: name != src.names[3]))
    assert len(frames) == 1 and frames[0].rig is not None and frames[0].index == 3
    with pytest.raises(SourceError, match="calibration"):
        SceneSource.from_folder(shared_data / "middlebury2001")  # Tsukuba and Venus come without one
    with pytest.raises(FileNotFoundError):
        SceneSource.from_folder(shared_data / "no-such-folder")
    with pytest.raises(SourceError):
        SceneSource([])


def test_scene_source_knows_the_first_scenes_range_when_it_read_it(shared_data):
    # the commands load the matcher's kernels (compiled per range) for it before the first frame
    from stereo_classic.datasets import demo_scene
    from stereo_classic.sources import PairSource, SceneSource

    assert SceneSource.demo().first_max_disparity == demo_scene().max_disparity is not None
    for folder in ("middlebury2014", "drivingstereo", "oakd"):
        src = SceneSource.from_folder(shared_data / folder)
        first = next(src.frames())
        assert src.first_max_disparity == first.max_disparity, folder
    assert SceneSource.from_folder(shared_data / "middlebury2014").first_max_disparity is not None
    assert not hasattr(PairSource, "first_max_disparity")  # files of pairs: the range is the command's




def test_names_keep_letters_and_spaces_and_replace_only_unsafe_characters(tmp_path):
    from stereo_classic.sources import PairSource

    stems = ["Straße links", "左 image", "a:b*c?", "café", "CAFÉ", "café_1", " .hidden", "x" * 300, "NUL"]
    pairs = [(tmp_path / f"{s}.png", tmp_path / "r.png") for s in stems]
    names = PairSource(pairs).names
    assert names[:4] == ["Straße links", "左 image", "a_b_c", "café"]
    assert names[4] == "CAFÉ_2" and names[5] == "café_1"  # case-insensitive collision; never reuses a given name
    assert names[6] == "hidden" and len(names[7].encode()) <= 200 and names[8] == "NUL_"
    assert len({n.casefold() for n in names}) == len(names)
    for n in names:  # every name makes a file on this file system
        (tmp_path / f"{n}_boxes.png").write_bytes(b"x")


def test_expand_pairs_names_the_real_cause(tmp_path):
    from stereo_classic.sources import SourceError, expand_pairs

    for i in range(3):
        (tmp_path / f"l{i}.png").write_bytes(b"x")
    (tmp_path / "r0.png").write_bytes(b"x")
    with pytest.raises(FileNotFoundError, match=r"--left .* is a directory, expected image files"):
        expand_pairs([str(tmp_path)], [str(tmp_path / "r0.png")])
    with pytest.raises(SourceError, match=r"these left image\(s\) have no right image: .*l1.png, .*l2.png"):
        expand_pairs([str(tmp_path / "l*.png")], [str(tmp_path / "r*.png")])
