"""Judging one feed's answers against the reference's: onsets missed, late, false and repeated, and how
well its fixes were matched to the road the vehicle truly drove (definitions in
:mod:`benchmarks.telematics`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from benchmarks.telematics_analysis import match_onsets, on_at, onsets, repeat_onsets
from benchmarks.telematics_feed import FeedAnswers
from benchmarks.telematics_fleet import STEP_S, Trajectories

__all__ = [
    "judge",
    "true_roads",
    "on_true_road",
    "BEFORE_INTERVALS",
    "AFTER_INTERVALS",
    "REPEAT_INTERVALS",
    "TRUE_ROAD_REACH_M",
]

#: A feed onset is the reference's if it comes at most this many fix intervals before it ...
BEFORE_INTERVALS = 2.0
#: ... or at most this many after it.
AFTER_INTERVALS = 3.0
#: An onset within this many fix intervals of the vehicle's previous warning answer is a repeat.
REPEAT_INTERVALS = 3.0
#: A fix is on the true road if matched to an edge the vehicle drove on within this distance of travel
#: before or after it, m: about 2.5 sigma of the noisier receiver along the road.
TRUE_ROAD_REACH_M = 20.0
#: The odometer keys' span per vehicle, m (longer than any vehicle's run).
ODOMETER_SPAN_M = 1e7


@dataclass
class _Tally:
    """What the vehicles of one feed add up to."""

    reference_onsets: int = 0
    onsets: int = 0
    missed: int = 0
    already_on: int = 0
    lateness: list[float] = field(default_factory=list)
    false: int = 0
    false_level_2: int = 0
    false_junction: int = 0
    false_level_2_junction: int = 0
    echoes: int = 0
    other_curve: int = 0
    repeats: int = 0
    reference_repeats: int = 0
    #: Each missed and false onset: its kind, the answer it is (the reference's for a missed one, the feed's for a
    #: false one) and the feed's answer then (its last before a missed onset, -1 if none).
    named: list[tuple[str, int, int]] = field(default_factory=list)


@dataclass(frozen=True)
class _Vehicle:
    """One vehicle's answers of a feed in time order: times, levels and the answers' indices."""

    times_s: np.ndarray
    levels: np.ndarray
    indices: np.ndarray


def _by_vehicle(trajectories: Trajectories, answers: FeedAnswers) -> dict[int, _Vehicle]:
    """A feed's answers split by vehicle, each in time order."""
    vehicles = trajectories.vehicle[answers.rows]
    order = np.argsort(vehicles, kind="stable")
    cuts = np.flatnonzero(np.diff(vehicles[order])) + 1
    split = {}
    for indices in np.split(order, cuts):
        if len(indices):
            times_s = trajectories.step[answers.rows[indices]] * STEP_S
            split[int(vehicles[indices[0]])] = _Vehicle(times_s, answers.level[indices], indices)
    return split


def _is_junction(place_id: str | None) -> bool:
    """Whether a lane or edge is a junction connection (SUMO's internal lanes and edges start with ':')."""
    return place_id is not None and place_id.startswith(":")


def _count_false(tally: _Tally, feed: _Vehicle, onset: int, answers: FeedAnswers) -> None:
    """Count a false warning: its highest level until it went off, and whether it came at a junction."""
    after = feed.levels[onset:]
    off = np.flatnonzero(after == 0)
    level_2 = int(after[: off[0] if len(off) else len(after)].max()) == 2
    answer = feed.indices[onset]
    junction = _is_junction(answers.matched_lane[answer]) or _is_junction(answers.target_edge[answer])
    tally.false += 1
    tally.named.append(("false", int(answer), int(answer)))
    tally.false_level_2 += level_2
    tally.false_junction += junction
    tally.false_level_2_junction += level_2 and junction


def _tally_vehicle(
    tally: _Tally,
    reference_of: tuple[_Vehicle, FeedAnswers],
    feed_of: tuple[_Vehicle, FeedAnswers],
    interval_s: float,
) -> None:
    """Add one vehicle's onsets (of the reference and the feed, each with its feed's answers): matched, those
    matched with another curve's, missed, false and repeated."""
    (reference, reference_answers), (feed, answers) = reference_of, feed_of
    before_s, after_s = BEFORE_INTERVALS * interval_s, AFTER_INTERVALS * interval_s
    reference_onsets, feed_onsets = onsets(reference.levels), onsets(feed.levels)
    reference_s, feed_s = reference.times_s[reference_onsets], feed.times_s[feed_onsets]
    tally.reference_onsets += len(reference_onsets)
    tally.onsets += len(feed_onsets)
    match = match_onsets(reference_s, feed_s, before_s, after_s)
    tally.lateness += [(feed_s[f] - reference_s[r]) / interval_s for r, f in match.pairs]
    tally.other_curve += sum(
        reference_answers.target_edge[reference.indices[reference_onsets[r]]]
        != answers.target_edge[feed.indices[feed_onsets[f]]]
        for r, f in match.pairs
    )
    for r in match.unmatched_reference:
        on = on_at(feed.times_s, feed.levels, reference_s[r] - before_s, reference_s[r])
        tally.already_on += on
        tally.missed += not on
        if not on:
            before = np.flatnonzero(feed.times_s <= reference_s[r])
            feed_answer = int(feed.indices[before[-1]]) if len(before) else -1
            tally.named.append(("missed", int(reference.indices[reference_onsets[r]]), feed_answer))
    for f in match.unmatched_feed:
        if on_at(reference.times_s, reference.levels, feed_s[f] - after_s, feed_s[f] + before_s):
            tally.echoes += 1
        else:
            _count_false(tally, feed, int(feed_onsets[f]), answers)
    gap_s = REPEAT_INTERVALS * interval_s
    tally.repeats += repeat_onsets(feed.times_s, feed.levels, gap_s)
    tally.reference_repeats += repeat_onsets(reference.times_s, reference.levels, gap_s)


def _lane_visits(trajectories: Trajectories) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each vehicle's lanes in driving order with the odometer reading where it entered and left each,
    keyed by vehicle (``vehicle * ODOMETER_SPAN_M + odometer``): the keys of the rows, of the visits'
    ends and starts, and each visit's edge."""
    t = trajectories
    order = np.lexsort((t.step, t.vehicle))
    vehicle, lane = t.vehicle[order], t.lane[order]
    travelled_m = np.where(np.diff(vehicle, prepend=-1) == 0, t.speed_mps[order] * STEP_S, 0.0)
    first_of_vehicle = np.flatnonzero(np.diff(vehicle, prepend=-1) != 0)
    odometer_m = np.cumsum(travelled_m)
    odometer_m -= np.repeat(odometer_m[first_of_vehicle], np.diff(np.append(first_of_vehicle, len(order))))
    keys = np.empty(len(order))
    keys[order] = vehicle * ODOMETER_SPAN_M + odometer_m
    starts = np.flatnonzero((np.diff(vehicle, prepend=-1) != 0) | (np.diff(lane, prepend=-1) != 0))
    ends = np.append(starts[1:], len(order)) - 1
    edges = np.array([lane_id.rpartition("_")[0] for lane_id in t.lanes], dtype=object)
    start_keys = vehicle[starts] * ODOMETER_SPAN_M + odometer_m[starts]
    end_keys = vehicle[ends] * ODOMETER_SPAN_M + odometer_m[ends]
    return keys, end_keys, start_keys, edges[lane[starts]]


def true_roads(trajectories: Trajectories, rows: np.ndarray) -> list[set[str]]:
    """The true roads of fixes taken at trajectory ``rows``: the edges the vehicle drove on within
    TRUE_ROAD_REACH_M of travel before or after each (an error along the road is not a wrong road, a wrong
    connection or side street is)."""
    keys, end_keys, start_keys, visit_edges = _lane_visits(trajectories)
    fix_keys = keys[rows]
    first = np.searchsorted(end_keys, fix_keys - TRUE_ROAD_REACH_M, side="left")
    last = np.searchsorted(start_keys, fix_keys + TRUE_ROAD_REACH_M, side="right")
    return [set(visit_edges[begin:end]) for begin, end in zip(first.tolist(), last.tolist(), strict=True)]


def on_true_road(lane_ids: Sequence[str | None], roads: list[set[str]]) -> np.ndarray:
    """Whether each matched lane (None: matched nothing) lies on an edge of its fix's true roads."""
    return np.array(
        [
            lane_id is not None and lane_id.rpartition("_")[0] in road
            for lane_id, road in zip(lane_ids, roads, strict=True)
        ],
        dtype=bool,
    )


def _matching(trajectories: Trajectories, answers: FeedAnswers) -> dict:
    """Shares of the fixes matched to the true road (:func:`true_roads`) at their answer and as the next answer
    confirmed them, to the true lane, and to nothing."""
    roads = true_roads(trajectories, answers.rows)
    on_road = on_true_road(answers.matched_lane.tolist(), roads)
    true_lanes = np.array(trajectories.lanes, dtype=object)[trajectories.lane[answers.rows]]
    fixes = max(len(answers.rows), 1)
    return {
        "true_road_share": float(on_road.sum() / fixes),
        "confirmed_true_road_share": float(on_true_road(answers.confirmed_lane.tolist(), roads).sum() / fixes),
        "true_lane_share": float((true_lanes == answers.matched_lane).sum() / fixes),
        "no_match_share": sum(lane is None for lane in answers.matched_lane) / fixes,
    }


def _lateness(values: list[float]) -> dict:
    """How late the matched onsets came, fix intervals: how many late, median, p90 and the latest."""
    if not values:
        return {"late": 0, "median": float("nan"), "p90": float("nan"), "max": float("nan")}
    array = np.asarray(values)
    return {
        "late": int((array > 1e-9).sum()),
        "median": float(np.median(array)),
        "p90": float(np.percentile(array, 90)),
        "max": float(array.max()),
    }


def judge(
    trajectories: Trajectories, reference: FeedAnswers, answers: FeedAnswers, interval_s: float, matching: bool
) -> dict:
    """A feed's figures against the reference (and its map matching's when it sent fixes)."""
    tally = _Tally()
    reference_by_vehicle = _by_vehicle(trajectories, reference)
    feed_by_vehicle = _by_vehicle(trajectories, answers)
    empty = _Vehicle(np.zeros(0), np.zeros(0, dtype=np.int8), np.zeros(0, dtype=np.int64))
    for vehicle in sorted(set(reference_by_vehicle) | set(feed_by_vehicle)):
        _tally_vehicle(
            tally,
            (reference_by_vehicle.get(vehicle, empty), reference),
            (feed_by_vehicle.get(vehicle, empty), answers),
            interval_s,
        )
    figures = {name: value for name, value in vars(tally).items() if name not in ("lateness", "named")}
    figures |= {
        "fixes": len(answers.rows),
        "interval_s": interval_s,
        "missed_share": tally.missed / max(tally.reference_onsets, 1),
        "false_share": tally.false / max(tally.reference_onsets, 1),
        "late_intervals": _lateness(tally.lateness),
        "us_per_fix": 1000.0 * answers.server_ms / max(len(answers.rows), 1),
    }
    if matching:
        figures["matching"] = _matching(trajectories, answers)
    figures["onsets_named"] = _named(trajectories, reference, answers, tally.named)
    return figures


def _named(
    trajectories: Trajectories, reference: FeedAnswers, answers: FeedAnswers, named: list[tuple[str, int, int]]
) -> list[dict]:
    """Where each missed and false onset came, to trace its cause: the vehicle, the time, its speed, the lane it
    truly drove, the lane the feed's fix then was matched to (for a missed onset, its last fix before the
    reference's onset) and the edge of the warned curve (for a missed onset, the one the reference warned of)."""
    records = []
    for kind, answer, feed_answer in named:
        source = reference if kind == "missed" else answers
        row = int(source.rows[answer])
        records.append(
            {
                "kind": kind,
                "vehicle": trajectories.vehicle_ids[int(trajectories.vehicle[row])],
                "time_s": round(float(trajectories.step[row]) * STEP_S, 1),
                "speed_kmh": round(float(trajectories.speed_mps[row]) * 3.6, 1),
                "true_lane": trajectories.lanes[int(trajectories.lane[row])],
                "matched_lane": answers.matched_lane[feed_answer] if feed_answer >= 0 else None,
                "curve_edge": source.target_edge[answer],
                "level": int(source.level[answer]),
            }
        )
    return records
