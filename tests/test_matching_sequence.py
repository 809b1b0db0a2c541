"""Map matching over the fix sequence (csws.road.hmm) against constructed truth: the junction town of
tests/junction_town.py, driven at 1 Hz with σ 3 m position noise and 5 degree heading noise (fixed seeds).

The truth is the path each drive takes; the side streets' curves (R 20 m, 40 m after the junction) are
tight enough for a level-2 warning at 50 km/h, which the tests check the engine gives on the side street's
connection, so that a match onto it would show as a warning.
"""

from __future__ import annotations

import math
from pathlib import Path

import msgspec
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from junction_town import SIDE_RADIUS_M, drive

from csws.engine import Engine, VehicleInput
from csws.road.hmm import Fixes, MatchState, Placed, SequenceMatcher, Track, transition_scale_m
from csws.road.match_settings import MatchSettings
from csws.road.matching import Probes, lane_point
from csws.road.roadmap import RoadMap
from csws.standard import Level
from csws.state import CLOCK_JUMP_S

#: Fixed seeds of the noisy drives (each a new phase of the fixes and new noise).
SEEDS = range(40)
#: Speeds driven, m/s: 30 and 70 km/h.
SPEEDS_MPS = (8.3, 19.4)


def _connection(town: RoadMap, from_lane: str, to_lane: str) -> str:
    """The internal lane of the connection from one lane to another."""
    (via,) = town.expand_path([from_lane, to_lane])[1:-1]
    return via


def _side_lanes(town: RoadMap) -> set[str]:
    """The side streets' lanes and the connections into them."""
    return {"JS_0", "JN_0", _connection(town, "WJ_0", "JS_0"), _connection(town, "WJ_0", "JN_0")}


def _fixes(xy: np.ndarray, time_s: np.ndarray, heading_deg: np.ndarray, speed_mps: float | None = None) -> Fixes:
    speed = None if speed_mps is None else np.full(len(time_s), speed_mps)
    return Fixes.of(Probes.everywhere(xy), time_s, heading_deg, speed)


def _online(matcher: SequenceMatcher, xy: np.ndarray, time_s: np.ndarray, heading_deg: np.ndarray, speed_mps: float):
    """Match a drive fix by fix as the service does, each fix continuing the last one's track."""
    track: Track | None = None
    answers = []
    for k in range(len(time_s)):
        one = matcher.match(_fixes(xy[k : k + 1], time_s[k : k + 1], heading_deg[k : k + 1], speed_mps), [track])
        track = one.tracks[0]
        answers.append((one.lane_id[0], float(one.lane_pos_m[0]), one.placed[0], one.reason[0]))
    return answers


def test_the_side_streets_curve_warns_from_its_connection(town: RoadMap) -> None:
    # What a wrong match would cost: on the connection into the side street at 70 km/h the path ahead turns
    # into it and its R 20 m curve (V_w far below 70 km/h, Tables 1-2) is warned of at level 2.
    into_side = _connection(town, "WJ_0", "JS_0")
    answer = Engine(town).evaluate(VehicleInput("v", "M1", 70.0, into_side, 1.0))
    assert answer.warning.level == Level.LEVEL_2
    assert answer.warning.target is not None and answer.warning.target.curve_id.startswith("JS@")
    assert answer.warning.target.radius_m == pytest.approx(SIDE_RADIUS_M, rel=0.05)


@pytest.mark.parametrize("speed_mps", SPEEDS_MPS)
def test_driving_straight_through_the_junction_never_matches_a_side_street(
    town: RoadMap, matcher: SequenceMatcher, speed_mps: float
) -> None:
    side = _side_lanes(town)
    engine = Engine(town)
    for seed in SEEDS:
        route = drive(town, ["WJ_0", "JE_0"], speed_mps, seed)
        answers = _online(matcher, route.xy, route.time_s, route.heading_deg, speed_mps)
        assert all(lane is not None for lane, *_ in answers), seed
        assert not side & {lane for lane, *_ in answers}, seed
        for k, (lane, pos_m, _placed, _reason) in enumerate(answers):
            vehicle = VehicleInput(f"v{seed}", "M1", speed_mps * 3.6, lane, pos_m, timestamp_s=float(k))
            warning = engine.evaluate(vehicle).warning
            assert not any(t.curve_id.startswith(("JS@", "JN@")) for t in warning.triggers), (seed, k)


@settings(max_examples=30, deadline=None)
@given(
    speed_mps=st.floats(5.0, 25.0),
    seed=st.integers(0, 2**32 - 1),
    sigma_m=st.floats(0.5, 4.0),
    to_side=st.sampled_from(["JS_0", "JN_0", "JE_0"]),
)
def test_no_fix_is_placed_off_the_path_toward_another_road(
    town: RoadMap, matcher: SequenceMatcher, speed_mps: float, seed: int, sigma_m: float, to_side: str
) -> None:
    # Whatever the speed, noise and phase: a vehicle is never placed on a road it does not take (the other side
    # street, or straight on when it turns, is allowed only as the road's own continuation before the turn shows).
    path = set(town.expand_path(["WJ_0", to_side]))
    continuation = {_connection(town, "WJ_0", "JE_0"), "JE_0"}
    route = drive(town, ["WJ_0", to_side], speed_mps, seed, sigma_m=sigma_m)
    answers = _online(matcher, route.xy, route.time_s, route.heading_deg, speed_mps)
    first_off_main = next((k for k, lane in enumerate(route.lane_id) if lane == to_side), len(answers))
    for k, (lane, _pos, _placed, _reason) in enumerate(answers):
        allowed = path if k >= first_off_main or to_side == "JE_0" else path | continuation
        true_xy = lane_point(town, route.lane_id[k], float(route.lane_pos_m[k]))
        if k == 0 and math.dist(route.xy[k], true_xy) > matcher.settings.tolerance_m:
            allowed = allowed | {None}  # a first fix the noise put beyond the search: nothing to dead-reckon from
        assert lane in allowed, (k, lane, route.lane_id[k])


@pytest.mark.parametrize("speed_mps", SPEEDS_MPS)
def test_turning_into_the_side_street_is_matched_from_its_first_fix_there(
    town: RoadMap, matcher: SequenceMatcher, speed_mps: float
) -> None:
    onto_side = {"JS_0", _connection(town, "WJ_0", "JS_0")}
    for seed in SEEDS:
        route = drive(town, ["WJ_0", "JS_0"], speed_mps, seed)
        answers = _online(matcher, route.xy, route.time_s, route.heading_deg, speed_mps)
        first_on_side = route.lane_id.index("JS_0")
        assert all(lane in onto_side for lane, *_ in answers[first_on_side:]), seed
        # Before the side street, a fix in the junction is on the turn or still on the road's continuation.
        road_on = {_connection(town, "WJ_0", "JE_0"), "JE_0"}
        assert {lane for lane, *_ in answers[:first_on_side]} <= {"WJ_0", *onto_side, *road_on}, seed


def test_an_undecided_fix_in_the_junction_is_placed_on_the_roads_continuation(
    town: RoadMap, matcher: SequenceMatcher
) -> None:
    # A vehicle 14 m before the junction, then a fix where the connections from its lane start together,
    # heading up to 30 degrees into a turn: the turn is likely but not shown, so the fix is placed on the
    # road's own continuation (on the turn's best candidate: deferred); the next fix, 10 m into the side
    # street, is placed there.
    straight_on = _connection(town, "WJ_0", "JE_0")
    entry_end = town.lane_shape("WJ_0")[-1]
    before = Fixes.of(Probes.everywhere(np.array([entry_end - (14.0, 0.0)])), [0.0], [90.0])
    track = matcher.match(before, [None]).tracks[0]
    for to_side, turn_sign, side_heading_deg in (("JS_0", 1.0, 180.0), ("JN_0", -1.0, 0.0)):
        shared_start = town.lane_shape(_connection(town, "WJ_0", to_side))[[1]]
        placed = []
        for into_turn_deg in (10.0, 20.0, 30.0):
            inside = Fixes.of(Probes.everywhere(shared_start), [1.0], [90.0 + turn_sign * into_turn_deg])
            answer = matcher.match(inside, [track])
            assert answer.lane_id[0] == straight_on, (to_side, into_turn_deg)
            placed.append(answer.placed[0])
        assert Placed.DEFERRED in placed
        on_side = Fixes.of(Probes.everywhere(town.lane_shape(to_side)[[10]]), [2.0], [side_heading_deg])
        assert matcher.match(on_side, answer.tracks).lane_id == [to_side]


def test_a_ten_second_gap_of_fixes_is_bridged_by_dead_reckoning(town: RoadMap, matcher: SequenceMatcher) -> None:
    # 14 m/s along the main road; from the 6th fix on, for 10 s, the fixes are 40 m off any road (multipath),
    # straight through the junction: each is placed along the road as far as the time since the last match
    # and the speed say, within the noise of that last match; after them the fixes match again.
    speed_mps = 14.0
    route = drive(town, ["WJ_0", "JE_0"], speed_mps, seed=7, start_m=100.0)
    xy = route.xy.copy()
    lost = slice(6, 16)
    xy[lost] += (0.0, 100.0)
    answers = _online(matcher, xy, route.time_s, route.heading_deg, speed_mps)
    assert all(lane is not None and reason is None for lane, _pos, _placed, reason in answers)
    assert [placed for _lane, _pos, placed, _reason in answers[lost]] == [Placed.DEAD_RECKONED] * 10
    path = town.expand_path(["WJ_0", "JE_0"])
    starts = dict(zip(path, np.cumsum([0.0] + [town.lane(lane).length_m for lane in path[:-1]]), strict=True))
    truth_m = [starts[lane] + pos for lane, pos in zip(route.lane_id, route.lane_pos_m, strict=True)]
    placed_m = [starts[lane] + pos for lane, pos, _placed, _reason in answers]
    assert np.abs(np.subtract(placed_m, truth_m))[lost].max() < 3 * 3.0  # three σ of the last matched fix
    assert all(placed == Placed.MATCHED for _lane, _pos, placed, _reason in answers[16:])


def test_dead_reckoning_ends_after_its_time(town: RoadMap, matcher: SequenceMatcher) -> None:
    limit_s = matcher.settings.dead_reckoning_s
    on_road = Fixes.of(Probes.everywhere(np.array([[100.0, 0.0]])), [0.0], [90.0], [10.0])
    track = matcher.match(on_road, [None]).tracks[0]
    off = np.array([[150.0, 80.0]])
    within = matcher.match(Fixes.of(Probes.everywhere(off), [limit_s], [90.0], [10.0]), [track])
    beyond = matcher.match(Fixes.of(Probes.everywhere(off), [limit_s + 0.5], [90.0], [10.0]), [track])
    assert within.placed == [Placed.DEAD_RECKONED] and within.lane_pos_m[0] == pytest.approx(
        track.state.lane_pos_m + 10.0 * limit_s
    )
    assert beyond.lane_id == [None] and beyond.reason[0].startswith("no lane within 10 m")
    assert beyond.tracks[0] == track  # the sequence is kept: a fix on the road later continues it


def test_a_fix_that_comes_late_leaves_the_sequence_where_the_newest_fix_put_it(
    town: RoadMap, matcher: SequenceMatcher
) -> None:
    # 10 m/s along the main road, fixes at t = 10..13; then the fix of t = 2 arrives late. It is placed by itself
    # (where it was), and the next fix, 40 m off the road at t = 14, is dead-reckoned from t = 13, not from the late
    # fix (12 s before it: beyond the dead reckoning's 10 s), and confirms the fix of t = 13.
    def fix(x_m: float, y_m: float, time_s: float) -> Fixes:
        return Fixes.of(Probes.everywhere(np.array([[x_m, y_m]])), [time_s], [90.0], [10.0])

    track: Track | None = None
    for time_s in (10.0, 11.0, 12.0, 13.0):
        track = matcher.match(fix(10.0 * time_s, 0.0, time_s), [track]).tracks[0]
    assert track is not None and track.state.lane_id == "WJ_0"
    late = matcher.match(fix(20.0, 0.0, 2.0), [track])
    assert late.lane_id == ["WJ_0"] and late.lane_pos_m[0] == pytest.approx(track.state.lane_pos_m - 110.0, abs=0.5)
    assert late.placed == [Placed.MATCHED] and late.tracks == [track] and late.confirmed == [None]
    after = matcher.match(fix(140.0, 40.0, 14.0), late.tracks)
    assert after.placed == [Placed.DEAD_RECKONED]
    assert after.lane_pos_m[0] == pytest.approx(track.state.lane_pos_m + 10.0)
    on_road = matcher.match(fix(150.0, 0.0, 15.0), [track])
    assert on_road.confirmed[0] is not None and on_road.confirmed[0].time_s == 13.0
    # Further back than a clock jump (as the engine takes it), the vehicle's clock started again: the fix continues.
    restarted = matcher.match(fix(20.0, 0.0, 13.0 - CLOCK_JUMP_S - 1.0), [track])
    assert restarted.tracks[0] is not track and restarted.tracks[0].state.time_s == 13.0 - CLOCK_JUMP_S - 1.0


def test_a_gap_without_fixes_continues_the_sequence(town: RoadMap, matcher: SequenceMatcher) -> None:
    route = drive(town, ["WJ_0", "JE_0"], 14.0, seed=3, start_m=150.0)
    keep = np.r_[0:4, 14 : len(route.time_s)]  # no fix for 10 s, across the junction
    answers = _online(matcher, route.xy[keep], route.time_s[keep], route.heading_deg[keep], 14.0)
    assert [placed for _lane, _pos, placed, _reason in answers] == [Placed.MATCHED] * len(keep)
    assert answers[4][0] == "JE_0" and route.lane_id[keep[4]] == "JE_0"
    assert {lane for lane, *_ in answers} <= set(town.expand_path(["WJ_0", "JE_0"]))


@pytest.mark.parametrize("to_lane", ["JE_0", "JS_0", "JN_0"])
def test_a_whole_trace_is_matched_on_the_path_driven(town: RoadMap, matcher: SequenceMatcher, to_lane: str) -> None:
    path = set(town.expand_path(["WJ_0", to_lane]))
    for seed in SEEDS:
        route = drive(town, ["WJ_0", to_lane], 13.9, seed)
        trace = matcher.match_trace(_fixes(route.xy, route.time_s, route.heading_deg))
        assert set(trace.lane_id) <= path, seed
        assert trace.placed == [Placed.MATCHED] * len(route.time_s)
        assert (
            np.abs(trace.lane_pos_m - route.lane_pos_m)[np.array(trace.lane_id) == np.array(route.lane_id)].max() < 12
        )


@pytest.mark.parametrize("to_lane", ["JS_0", "JN_0"])
def test_a_fix_in_the_junction_is_on_the_turn_once_the_next_fix_shows_it(
    town: RoadMap, matcher: SequenceMatcher, to_lane: str
) -> None:
    # The fixes whose next fix is on the side street: matched with a lag of one fix (what the online matcher
    # decides once that fix arrives) they lie on the path driven at least as often as answered at once, and
    # nearly always (a next fix no candidate of this one reaches starts the sequence afresh and decides
    # nothing; a fix without a candidate is dead-reckoned along the road whatever the lag).
    path = set(town.expand_path(["WJ_0", to_lane]))
    online_on_path, lagged_on_path, shown = 0, 0, 0
    for seed in SEEDS:
        route = drive(town, ["WJ_0", to_lane], 11.0, seed)
        lagged = matcher.match_trace(_fixes(route.xy, route.time_s, route.heading_deg), lag=1)
        online = _online(matcher, route.xy, route.time_s, route.heading_deg, 11.0)
        for k in range(len(route.time_s) - 1):
            if route.lane_id[k + 1] == to_lane and lagged.placed[k] == Placed.MATCHED:
                shown += 1
                lagged_on_path += lagged.lane_id[k] in path
                online_on_path += online[k][0] in path
    assert lagged_on_path >= online_on_path
    assert lagged_on_path >= 0.95 * shown


@pytest.mark.parametrize("to_lane", ["JE_0", "JS_0", "JN_0"])
def test_each_answer_confirms_the_last_fix_as_a_lag_of_one_fix_places_it(
    town: RoadMap, matcher: SequenceMatcher, to_lane: str
) -> None:
    # Online, each fix's answer carries the vehicle's last matched fix placed on the path the new fix makes
    # most probable: the trace matched with a lag of one fix, fix by fix, and never off the path driven
    # toward another road.
    path = set(town.expand_path(["WJ_0", to_lane]))
    confirmed_count, later_fixes = 0, 0
    for seed in SEEDS[:10]:
        route = drive(town, ["WJ_0", to_lane], 11.0, seed)
        lagged = matcher.match_trace(_fixes(route.xy, route.time_s, route.heading_deg), lag=1)
        answered = [lane for lane, *_ in _online(matcher, route.xy, route.time_s, route.heading_deg, 11.0)]
        index_at = {float(t): k for k, t in enumerate(route.time_s)}
        for k, confirmed in enumerate(lagged.confirmed):
            if confirmed is None:
                continue
            earlier = index_at[confirmed.time_s]
            assert earlier < k
            assert (confirmed.lane_id, confirmed.lane_pos_m) == (lagged.lane_id[earlier], lagged.lane_pos_m[earlier])
            assert confirmed.revised == (confirmed.lane_id != answered[earlier])
            assert confirmed.lane_id in path, (seed, k)
            confirmed_count += 1
        later_fixes += len(route.time_s) - 1
    assert confirmed_count >= 0.9 * later_fixes


def test_a_fix_answered_on_the_roads_continuation_is_confirmed_on_the_turn_the_next_fix_shows(
    town: RoadMap, matcher: SequenceMatcher
) -> None:
    # The fix in the junction heading 30 degrees into the turn is answered on the road's continuation
    # (deferred); the next fix, 10 m into the side street, places it on the connection into that street:
    # revised, at that fix's time. A vehicle going straight on has its fix confirmed where it was answered.
    entry_end = town.lane_shape("WJ_0")[-1]
    before = Fixes.of(Probes.everywhere(np.array([entry_end - (14.0, 0.0)])), [0.0], [90.0])
    start = matcher.match(before, [None])
    assert start.confirmed == [None]  # a first fix confirms nothing
    for to_side, turn_sign, side_heading_deg in (("JS_0", 1.0, 180.0), ("JN_0", -1.0, 0.0)):
        shared_start = town.lane_shape(_connection(town, "WJ_0", to_side))[[1]]
        inside = Fixes.of(Probes.everywhere(shared_start), [1.0], [90.0 + turn_sign * 30.0])
        answer = matcher.match(inside, start.tracks)
        assert answer.placed == [Placed.DEFERRED]
        on_side = Fixes.of(Probes.everywhere(town.lane_shape(to_side)[[10]]), [2.0], [side_heading_deg])
        (confirmed,) = matcher.match(on_side, answer.tracks).confirmed
        assert confirmed is not None
        assert (confirmed.time_s, confirmed.lane_id) == (1.0, _connection(town, "WJ_0", to_side))
        assert confirmed.revised
    straight_on = _connection(town, "WJ_0", "JE_0")
    inside = Fixes.of(Probes.everywhere(town.lane_shape(straight_on)[[1]]), [1.0], [90.0])
    answer = matcher.match(inside, start.tracks)
    ahead = Fixes.of(Probes.everywhere(town.lane_shape("JE_0")[[0]] + (10.0, 0.0)), [2.0], [90.0])
    (confirmed,) = matcher.match(ahead, answer.tracks).confirmed
    assert confirmed is not None
    assert (confirmed.lane_id, confirmed.revised) == (answer.lane_id[0], False)


def test_a_lag_as_long_as_the_trace_is_the_whole_trace_and_no_lag_the_fix_alone(
    town: RoadMap, matcher: SequenceMatcher
) -> None:
    route = drive(town, ["WJ_0", "JS_0"], 13.9, seed=5)
    fixes = _fixes(route.xy, route.time_s, route.heading_deg)
    whole = matcher.match_trace(fixes)
    assert matcher.match_trace(fixes, lag=len(route.time_s)).lane_id == whole.lane_id
    alone, track = [], None
    for k in range(len(route.time_s)):
        answer = matcher.match(
            _fixes(route.xy[k : k + 1], route.time_s[k : k + 1], route.heading_deg[k : k + 1]), [track]
        )
        track = answer.tracks[0]
        alone.append(track.state.candidates[0])  # the most probable candidate, before any deferral
    assert matcher.match_trace(fixes, lag=0).lane_id == alone
    with pytest.raises(ValueError, match="lag"):
        matcher.match_trace(fixes, lag=-1)


def test_a_batch_of_vehicles_is_matched_as_each_alone(town: RoadMap, matcher: SequenceMatcher) -> None:
    drives = [drive(town, ["WJ_0", to], 11.0, seed) for seed, to in enumerate(["JE_0", "JS_0", "JN_0", "JE_0"])]
    steps = min(len(d.time_s) for d in drives)
    together: list[Track | None] = [None] * len(drives)
    alone: list[Track | None] = [None] * len(drives)
    for k in range(steps):
        xy = np.array([d.xy[k] for d in drives])
        batch = matcher.match(
            _fixes(xy, np.full(len(drives), float(k)), np.array([d.heading_deg[k] for d in drives])), together
        )
        together = batch.tracks
        for v, d in enumerate(drives):
            one = matcher.match(_fixes(d.xy[k : k + 1], np.array([float(k)]), d.heading_deg[k : k + 1]), [alone[v]])
            alone[v] = one.tracks[0]
            assert (batch.lane_id[v], batch.placed[v]) == (one.lane_id[0], one.placed[0])
            assert batch.lane_pos_m[v] == pytest.approx(one.lane_pos_m[0])
        assert together == alone


def test_a_fix_sent_again_is_placed_where_it_was(town: RoadMap, matcher: SequenceMatcher) -> None:
    # A resent fix (the same time and place) brings nothing new: the same placement, the track unchanged;
    # beside a new vehicle's fix in the same batch, matched as ever.
    route = drive(town, ["WJ_0", "JS_0"], 13.9, seed=2)
    track = None
    for k in range(len(route.time_s)):
        fix = _fixes(route.xy[k : k + 1], route.time_s[k : k + 1], route.heading_deg[k : k + 1])
        first = matcher.match(fix, [track])
        both = Fixes.of(
            Probes.everywhere(np.vstack([route.xy[k], route.xy[k]])),
            np.repeat(route.time_s[k], 2),
            np.repeat(route.heading_deg[k], 2),
        )
        again = matcher.match(both, [first.tracks[0], None])
        assert again.tracks[0] is first.tracks[0]
        assert (again.lane_id[0], again.placed[0], again.reason[0]) == (first.lane_id[0], first.placed[0], None)
        assert (again.lane_pos_m[0], again.distance_m[0]) == (first.lane_pos_m[0], first.distance_m[0])
        assert again.lane_id[1] is not None and again.tracks[1] is not None
        alone = matcher.match(fix, first.tracks)
        assert (alone.lane_id, alone.placed, alone.tracks) == (first.lane_id, first.placed, first.tracks)
        track = first.tracks[0]


def test_the_state_is_small_and_survives_messagepack(town: RoadMap, matcher: SequenceMatcher) -> None:
    route = drive(town, ["WJ_0", "JS_0"], 13.9, seed=1)
    track = None
    for k in range(len(route.time_s)):
        track = matcher.match(
            _fixes(route.xy[k : k + 1], route.time_s[k : k + 1], route.heading_deg[k : k + 1]), [track]
        ).tracks[0]
        assert track is not None
        encoded = msgspec.msgpack.encode(track.state)
        assert msgspec.msgpack.decode(encoded, type=MatchState) == track.state
        assert len(encoded) < 60 + 40 * len(track.state.candidates)
        assert len(track.state.candidates) <= matcher.settings.max_candidates


def test_the_fixs_accuracy_widens_the_search(town: RoadMap) -> None:
    matcher = SequenceMatcher([town], MatchSettings(tolerance_m=10.0, search_sigmas=2.5))
    far = Probes.everywhere(np.array([[100.0, 15.0]]))  # 15 m from the main road's lane
    assert matcher.match(Fixes.of(far, [0.0], [90.0]), [None]).lane_id == [None]
    wide = matcher.match(Fixes.of(far, [0.0], [90.0], accuracy_m=[8.0]), [None])
    assert wide.lane_id == ["WJ_0"] and wide.distance_m[0] == pytest.approx(15.0, abs=0.01)
    assert wide.reason == [None]
    assert matcher.match(Fixes.of(far, [0.0], [90.0]), [None]).reason[0] == "no lane within 10 m"
    assert math.isclose(MatchSettings().accuracy_m * MatchSettings().search_sigmas, MatchSettings().tolerance_m)


def test_settings_of_the_sequence_matcher_are_checked() -> None:
    for bad in ({"accuracy_m": 0.0}, {"commit_share": 0.2}, {"lane_change_log_p": 0.5}, {"max_candidates": 0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            MatchSettings(**bad)


def test_lanes_the_map_no_longer_has_are_dropped_from_a_state(town: RoadMap, matcher: SequenceMatcher) -> None:
    stale = MatchState(0.0, 100.0, 0.0, 10.0, "gone_0", 5.0, 0.0, Placed.MATCHED, ("gone_0",), (5.0,), (0.0,))
    answer = matcher.match(Fixes.of(Probes.everywhere(np.array([[110.0, 0.0]])), [1.0], [90.0]), [Track(0, stale)])
    assert answer.lane_id == ["WJ_0"] and answer.placed == [Placed.MATCHED]


def test_a_path_of_the_town_is_what_the_builder_says(tmp_path: Path, town: RoadMap) -> None:
    assert {lane for lane in town.lane_ids if not town.lane(lane).is_internal} == {"WJ_0", "JE_0", "JS_0", "JN_0"}
    assert town.lane(_connection(town, "WJ_0", "JE_0")).continues_road
    assert not town.lane(_connection(town, "WJ_0", "JS_0")).continues_road


@settings(max_examples=20, deadline=None)
@given(st.floats(min_value=1.0, max_value=20.0), st.floats(min_value=0.0, max_value=15.0))
def test_the_transition_scale_has_the_spread_of_the_route_and_the_two_fixes_noise(beta_m, sigma_m) -> None:
    """|route - straight| between two noisy fixes: the map's exponential (Laplace, scale beta) plus the difference
    of the two fixes' Gaussian errors along the way; the scale given has that sum's standard deviation."""
    rng = np.random.default_rng(7)
    count = 200_000
    departure_m = rng.laplace(0.0, beta_m, count) + rng.normal(0.0, sigma_m, count) - rng.normal(0.0, sigma_m, count)
    scale_m = float(transition_scale_m(beta_m, np.array([sigma_m]))[0])
    assert math.sqrt(2.0) * scale_m == pytest.approx(float(np.std(departure_m)), rel=0.02)
    assert scale_m >= max(beta_m, sigma_m)
