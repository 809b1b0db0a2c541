"""A vehicle standing still at a junction's stop line, matched over its fixes (csws.road.hmm) at sigma 8 m.

The truth is constructed: a truck on the junction town's main road (tests/junction_town.py) drives up to
GAP_M before the end of its lane, waits there, then turns into the south side street. While it waits,
its fixes scatter metres into the junction: by geometry alone (the nearest lane agreeing with the
heading) a fix past the lane's end lands on a connection, as the test derives from the normal
distribution and counts on the fixes themselves. The matcher, told by the fixes' speeds that the
vehicle stands still, keeps on the main road every waiting fix that lies, with the one before it,
within 2 sigma of the truck (a share of the waiting fixes the test derives: exp(-2) of the fixes
lie farther, by the chi-square law of two axes).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from csws.road.hmm import Fixes, SequenceMatcher, Track
from csws.road.match_settings import MatchSettings
from csws.road.matching import Probes
from csws.road.roadmap import RoadMap

#: The receiver: sigma 8 m per axis, 5 degree heading, 0.5 km/h speed (as the telematics benchmark's).
SIGMA_M, HEADING_SIGMA_DEG, SPEED_SIGMA_MPS = 8.0, 5.0, 0.5 / 3.6
#: The truck stops this far before the end of its lane, m.
GAP_M = 2.0
#: Seconds of approach at APPROACH_MPS, of waiting, and of driving off into the side street at DRIVE_OFF_MPS.
APPROACH_S, WAIT_S, DRIVE_OFF_S = 6, 30, 16
APPROACH_MPS, DRIVE_OFF_MPS = 8.0, 5.0
SEEDS = range(20)


def _along(town: RoadMap, path: tuple[str, ...], s_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The points, headings (degrees clockwise from north) and lanes at arc lengths along a path of lanes."""
    shapes = [np.asarray(town.lane_shape(lane)) for lane in path]
    vertex_s = [np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T)))) for shape in shapes]
    offsets = np.concatenate(([0.0], np.cumsum([v[-1] for v in vertex_s])))
    xy, heading_deg, lanes = [], [], []
    for s in s_m.tolist():
        k = min(int(np.searchsorted(offsets, s, side="right")) - 1, len(path) - 1)
        along = s - offsets[k]
        shape, v = shapes[k], vertex_s[k]
        xy.append((np.interp(along, v, shape[:, 0]), np.interp(along, v, shape[:, 1])))
        segment = min(max(int(np.searchsorted(v, along, side="right")) - 1, 0), len(shape) - 2)
        dx, dy = shape[segment + 1] - shape[segment]
        heading_deg.append((90.0 - math.degrees(math.atan2(dy, dx))) % 360.0)
        lanes.append(path[k])
    return np.array(xy), np.array(heading_deg), lanes


def _stop_and_turn(town: RoadMap) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The truck's true arc length along its path at each second, its true speed and the path."""
    path = town.expand_path(["WJ_0", "JS_0"])
    stop_s = float(np.hypot(*np.diff(np.asarray(town.lane_shape("WJ_0")), axis=0).T).sum()) - GAP_M
    approach = stop_s - APPROACH_MPS * np.arange(APPROACH_S, 0, -1)
    waiting = np.full(WAIT_S, stop_s)
    off = stop_s + 0.5 * DRIVE_OFF_MPS * np.arange(1, DRIVE_OFF_S + 1) ** 2 / DRIVE_OFF_S  # constant acceleration
    s_m = np.concatenate((approach, waiting, off))
    speed_mps = np.concatenate(
        (
            np.full(APPROACH_S, APPROACH_MPS),
            np.zeros(WAIT_S),
            DRIVE_OFF_MPS * np.arange(1, DRIVE_OFF_S + 1) / DRIVE_OFF_S,
        )
    )
    return s_m, speed_mps, list(path)


def _fixes(town: RoadMap, seed: int) -> tuple[Fixes, list[str], np.ndarray]:
    """The truck's noisy fixes (a speed over 0 or 0, as a receiver gives it), its true lane and position at each."""
    s_m, speed_mps, path = _stop_and_turn(town)
    xy, heading_deg, lanes = _along(town, tuple(path), s_m)
    rng = np.random.default_rng(seed)
    measured_xy = xy + rng.normal(0.0, SIGMA_M, xy.shape)
    measured_heading = (heading_deg + rng.normal(0.0, HEADING_SIGMA_DEG, len(s_m))) % 360.0
    measured_speed = np.maximum(speed_mps + rng.normal(0.0, SPEED_SIGMA_MPS, len(s_m)), 0.0)
    time_s = np.arange(len(s_m), dtype=float)
    accuracy = np.full(len(s_m), SIGMA_M)
    fixes = Fixes.of(Probes.everywhere(measured_xy), time_s, measured_heading, measured_speed, accuracy)
    return fixes, lanes, xy


def _online(matcher: SequenceMatcher, fixes: Fixes) -> list[str | None]:
    """Each fix's answer as the service gives it: matched when it arrives, continuing the last track."""
    track: Track | None = None
    answers = []
    for k in range(fixes.probes.count):
        one = fixes.probes.fix == k
        single = Fixes(
            Probes(1, np.zeros(int(one.sum()), dtype=np.intp), fixes.probes.xy[one], fixes.probes.map_index[one]),
            *(column[k : k + 1] for column in (fixes.time_s, fixes.heading_deg, fixes.speed_mps, fixes.accuracy_m)),
        )
        matches = matcher.match(single, [track])
        track = matches.tracks[0]
        answers.append(matches.lane_id[0])
    return answers


def _nearest_lane(town: RoadMap, fixes: Fixes, k: int) -> str | None:
    """The nearest lane to fix ``k`` whose direction lies within 45 degrees of its heading (geometry alone)."""
    x, y = fixes.probes.xy[k]
    heading_rad = math.radians(90.0 - float(fixes.heading_deg[k]))
    agreeing = [
        match
        for match in town.nearest_lanes(float(x), float(y), 3.0 * SIGMA_M)
        if abs(math.remainder(match.heading_rad - heading_rad, math.tau)) <= math.radians(45.0)
    ]
    return min(agreeing, key=lambda match: match.distance_m).lane_id if agreeing else None


def test_a_truck_waiting_at_the_stop_line_stays_on_its_road(town: RoadMap) -> None:
    matcher = SequenceMatcher([town])
    waiting = range(APPROACH_S + 1, APPROACH_S + WAIT_S)  # both this fix and the one before stand still
    near, matched_near, matched, nearest_on_road, total = 0, 0, 0, 0, 0
    for seed in SEEDS:
        fixes, lanes, true_xy = _fixes(town, seed)
        answers = _online(matcher, fixes)
        off_m = np.hypot(*(fixes.probes.xy - true_xy).T)
        for k in waiting:
            assert lanes[k] == "WJ_0"
            total += 1
            matched += answers[k] == "WJ_0"
            nearest_on_road += _nearest_lane(town, fixes, k) == "WJ_0"
            if off_m[k] < 2.0 * SIGMA_M and off_m[k - 1] < 2.0 * SIGMA_M:
                near += 1
                matched_near += answers[k] == "WJ_0"
    # by geometry alone, a fix past the lane's end (GAP_M ahead of the truck) lands on a connection
    geometry_share = 1.0 - 0.5 * math.erfc(GAP_M / (SIGMA_M * math.sqrt(2.0)))
    assert nearest_on_road / total == pytest.approx(geometry_share, abs=0.08)
    # every waiting fix within 2 sigma (with the one before) stays on the road; at least 1 - 2 exp(-2) of them are
    assert matched_near == near, (matched_near, near)
    assert near / total >= 1.0 - 2.0 * math.exp(-2.0)
    assert matched / total >= nearest_on_road / total + 0.25, (matched, nearest_on_road, total)


def test_a_truck_driving_off_is_matched_into_the_side_street(town: RoadMap) -> None:
    # Standing still does not hold the vehicle once it moves: a fix 20 m into the side street (sqrt(2) sigma off
    # the main road's line at least, heading 90 degrees off it) is on the side street.
    matcher = SequenceMatcher([town])
    s_m, _speed, _path = _stop_and_turn(town)
    for seed in SEEDS:
        fixes, lanes, _true_xy = _fixes(town, seed)
        answers = _online(matcher, fixes)
        into_side = [k for k, lane in enumerate(lanes) if lane == "JS_0"]
        far_in = [k for k in into_side if s_m[k] - s_m[into_side[0]] >= 20.0]
        assert far_in, seed
        assert all(answers[k] == "JS_0" for k in far_in), (seed, [answers[k] for k in far_in])


def test_without_speeds_standing_still_is_not_assumed(town: RoadMap) -> None:
    # A fix without a speed says nothing of standing still: its match is the one with both penalties off.
    plain = SequenceMatcher([town], MatchSettings(standstill_edge_log_p=0.0, standstill_junction_log_p=0.0))
    matcher = SequenceMatcher([town])
    for seed in range(5):
        fixes, _lanes, _true_xy = _fixes(town, seed)
        unknown = Fixes(
            fixes.probes, fixes.time_s, fixes.heading_deg, np.full_like(fixes.speed_mps, np.nan), fixes.accuracy_m
        )
        assert _online(matcher, unknown) == _online(plain, unknown)


@pytest.mark.parametrize(
    "field, value",
    [("standstill_edge_log_p", 0.5), ("standstill_junction_log_p", math.nan), ("standstill_mps", -1.0)],
)
def test_standstill_settings_are_checked(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        MatchSettings(**{field: value})
