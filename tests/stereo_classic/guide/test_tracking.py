"""Tracking: stable ids with the Hungarian assignment, approach speed and time to contact, track ends."""

from __future__ import annotations

import pytest

from stereo_classic.guide import GuideParams, Measurement, Tracker


def _m(label, lat, fwd, kind="object"):
    return Measurement(kind, label, lat, fwd, fwd)


def test_constant_approach_gives_speed_and_ttc():
    tracker = Tracker(GuideParams())
    for i in range(11):
        t = i / 10
        tracks = tracker.update([_m("person", 0.2, 4.0 - 1.5 * t)], t)
    (tr,) = tracks
    assert tr.track_id == 1 and tr.hits == 11
    assert tr.approach_mps == pytest.approx(1.5, rel=0.01)
    assert tr.ttc_s == pytest.approx(2.5 / 1.5, rel=0.02)
    assert tr.clock == 12


def test_two_crossing_objects_keep_their_ids():
    tracker = Tracker(GuideParams())
    ids = []
    for i in range(8):
        t = i / 10
        tracks = tracker.update([_m("person", -1.0 + 0.5 * t, 3.0), _m("person", 1.0 - 0.5 * t, 3.5)], t)
        ids.append({tr.track_id: round(tr.last.forward_m, 1) for tr in tracks})
    assert all(d == {1: 3.0, 2: 3.5} for d in ids)


def test_labels_are_not_mixed_and_receding_has_no_ttc():
    tracker = Tracker(GuideParams())
    for i in range(6):
        t = i / 10
        tracks = tracker.update([_m("chair", 0.0, 2.0 + t), _m("obstacle", 0.1, 2.0 + t, kind="obstacle")], t)
    assert sorted(tr.label for tr in tracks) == ["chair", "obstacle"] and len(tracker.tracks) == 2
    assert all(tr.approach_mps == pytest.approx(-1.0, rel=0.02) and tr.ttc_s is None for tr in tracks)


def test_short_history_has_no_speed_and_lost_tracks_end():
    tracker = Tracker(GuideParams(), max_misses=2)
    (tr,) = tracker.update([_m("dog", 0.0, 2.0)], 0.0)
    assert tr.approach_mps is None and tr.ttc_s is None and tr.distance_m == pytest.approx(2.0)
    for i in range(1, 4):
        assert tracker.update([], i / 10) == []
    assert tracker.tracks == []
    (new,) = tracker.update([_m("dog", 0.0, 2.0)], 0.5)
    assert new.track_id == 2                                       # ids are not reused


def test_a_drop_off_is_kept_unseen_while_ahead():
    """A drop-off edge coming closer at 1 m/s, then out of view: its track lives on while predicted ahead (at most
    DROP_HOLD_S), an obstacle's ends after max_misses frames."""
    from stereo_classic.guide.tracking import DROP_HOLD_S

    tracker = Tracker(GuideParams())
    for i in range(6):
        t = 0.1 * i
        tracker.update([Measurement("drop_off", "drop-off", 0.0, 2.5 - t, 2.5 - t, 1.0),
                        Measurement("obstacle", "obstacle", 1.0, 3.0, 3.0)], t)
    for i in range(6, 20):                                   # neither seen; the edge reaches the feet at 2.5 s
        tracker.update([], 0.1 * i)
        kinds = {tr.kind for tr in tracker.tracks}
        assert "drop_off" in kinds and ("obstacle" in kinds) == (i - 5 <= tracker.max_misses)
        (held,) = tracker.held(0.1 * i)
        assert held.predict_fitted(0.1 * i)[1] == pytest.approx(2.5 - 0.1 * i, abs=0.05)
    tracker.update([], 2.6)                                  # predicted behind the walker: ended
    assert not tracker.tracks
    still = Tracker(GuideParams())
    still.update([Measurement("drop_off", "drop-off", 0.0, 2.0, 2.0, 1.0)], 0.0)
    still.update([], DROP_HOLD_S)
    assert len(still.tracks) == 1
    still.update([], DROP_HOLD_S + 0.1)                      # not approached, but unseen for too long
    assert not still.tracks
