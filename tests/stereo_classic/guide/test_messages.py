"""Messages: phrasing, units, hysteresis, only-on-change, rate limit, dangers interrupting, Event checks."""

from __future__ import annotations

import json

import pytest

from stereo_classic.guide import Candidate, Event, GuideParams, MessagePolicy
from stereo_classic.guide.messages import (
    GROUND_UNKNOWN_TEXT,
    ground_unknown,
    say_direction,
    say_distance,
)


def _c(dist=3.0, bearing=0.0, approach=None, ttc=None, kind="object", label="person", tid=1, corridor=True):
    return Candidate(kind, label, tid, dist, dist, bearing, approach, ttc, corridor)


@pytest.mark.parametrize("metres, units, text", [(2.44, "metres", "2.4 metres"), (12.4, "metres", "12 metres"),
                                                 (2.44, "feet", "8 feet"), (0.2, "feet", "1 foot")])
def test_say_distance(metres, units, text):
    assert say_distance(metres, units) == text


def test_say_direction_in_words():
    assert say_direction(12, 2.0, "leftright") == "ahead"
    assert say_direction(11, -12.0, "leftright") == "slightly left"
    assert say_direction(2, 60.0, "clock") == "2 o'clock"


def test_priorities():
    policy = MessagePolicy(GuideParams())
    assert policy.priority(_c(0.8)) == "danger"
    assert policy.priority(_c(4.0, approach=2.5, ttc=1.6)) == "danger"
    assert policy.priority(_c(2.0)) == "warning"
    assert policy.priority(_c(4.0, approach=0.5, ttc=8.0)) == "warning"
    assert policy.priority(_c(2.0, corridor=False)) == "info"
    assert policy.priority(_c(2.0, kind="drop_off")) == "danger"


def test_hysteresis_no_flicker_between_distances_or_hours():
    policy = MessagePolicy(GuideParams(min_interval=0.1))
    said = []
    for i, (dist, bearing) in enumerate([(3.0, 14.0), (3.2, 16.0), (2.9, 14.0), (3.15, 18.0), (3.0, 13.0)]):
        said += policy.select([_c(dist, bearing, corridor=False)], frame=str(i), time_s=i * 0.5)
    assert [e.text for e in said] == ["person, 12 o'clock, 3.0 metres"]
    later = policy.select([_c(2.0, 40.0, corridor=False)], frame="x", time_s=5.0)
    assert [e.text for e in later] == ["person, 1 o'clock, 2.0 metres"]


def test_rate_limit_and_danger_interrupts():
    policy = MessagePolicy(GuideParams(min_interval=2.0, repeat_after=1.0))
    first = policy.select([_c(4.0, 0.0, corridor=False, tid=1), _c(3.0, 30.0, corridor=False, tid=2)],
                          frame="0", time_s=0.0)
    assert len(first) == 1 and first[0].track_id == 2            # one message, the nearest
    assert policy.select([_c(4.0, 0.0, corridor=False, tid=1), _c(3.0, 30.0, corridor=False, tid=2)],
                         frame="1", time_s=0.5) == []            # within min_interval
    danger = policy.select([_c(0.7, 0.0, tid=3)], frame="2", time_s=0.6)
    assert [(e.priority, e.interrupt) for e in danger] == [("danger", True)]
    again = policy.select([_c(0.7, 0.0, tid=3)], frame="3", time_s=1.7)   # repeated after repeat_after
    assert len(again) == 1 and again[0].priority == "danger"
    two = policy.select([_c(0.6, 0.0, tid=4), _c(0.8, 30.0, tid=5)], frame="3b", time_s=1.8)
    assert [(e.track_id, e.interrupt) for e in two] == [(4, True), (5, False)]   # the first cuts in, not each other
    later = policy.select([_c(4.0, 0.0, corridor=False, tid=1)], frame="4", time_s=4.0)
    assert [e.track_id for e in later] == [1]                    # not said earlier: still a change


def test_event_json_and_checks():
    e = Event("f", 1.23456, "object", "person", 4, 2.3456, 2.1, 2, 55.55, 1.234, None, "warning", "person")
    d = e.to_dict()
    assert d["time_s"] == 1.235 and d["distance_m"] == 2.35 and d["ttc_s"] is None
    json.dumps(d, allow_nan=False)
    with pytest.raises(ValueError, match="`kind`"):
        Event("f", 0.0, "tree", "x", None, None, None, 12, 0.0, None, None, "info", "x")
    with pytest.raises(ValueError, match="`clock`"):
        Event("f", 0.0, "object", "x", None, None, None, 13, 0.0, None, None, "info", "x")


def test_ground_unknown_is_said_once_and_again_only_after_the_ground_was_seen():
    policy = MessagePolicy(GuideParams())
    (e,) = policy.select([ground_unknown()], frame="f0", time_s=0.0)
    assert (e.kind, e.label, e.priority, e.clock, e.text) == ("status", "ground unknown", "warning", 12,
                                                               GROUND_UNKNOWN_TEXT)
    assert e.distance_m is None and e.nearest_m is None and not e.interrupt
    json.dumps(e.to_dict(), allow_nan=False)
    assert policy.select([ground_unknown()], frame="f1", time_s=5.0) == []    # still unknown: not repeated
    assert policy.select([], frame="f2", time_s=10.0) == []                    # the ground is seen
    assert [e.text for e in policy.select([ground_unknown()], frame="f3", time_s=15.0)] == [GROUND_UNKNOWN_TEXT]
    # a danger comes first; the status waits for the rate limit like any message that is not a danger
    policy = MessagePolicy(GuideParams())
    danger = Candidate("object", "person", 1, 0.6, 0.6, 0.0, None, None)
    assert [e.kind for e in policy.select([danger, ground_unknown()], frame="g0", time_s=0.0)] == ["object"]
    assert [e.kind for e in policy.select([danger, ground_unknown()], frame="g1", time_s=0.5)] == []
    assert [e.kind for e in policy.select([danger, ground_unknown()], frame="g2", time_s=3.0)] == ["status"]
