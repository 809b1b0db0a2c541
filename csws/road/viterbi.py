"""The forward (Viterbi) step of the sequence matcher (:mod:`csws.road.hmm`) for many vehicles at once.

Each vehicle's candidates of its previous fix and of its new fix are rows of flat arrays grouped by
vehicle; every (previous, new) pair of a vehicle is one row of the transition arrays, so a batch of
10,000 vehicles is a handful of numpy operations whatever the count of candidates of each.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csws.road.lanegraph import LaneGraph
from csws.road.match_settings import MatchSettings

__all__ = ["Previous", "Candidates", "Step", "forward_step", "kept_rows", "viterbi_path"]


@dataclass(frozen=True)
class Previous:
    """The candidates of the vehicles' previous fixes, flattened (rows by fix) with per-fix columns."""

    fix: np.ndarray
    lane: np.ndarray
    pos_m: np.ndarray
    log_p: np.ndarray
    start: np.ndarray
    count: np.ndarray
    xy: np.ndarray
    time_s: np.ndarray
    speed_mps: np.ndarray


@dataclass(frozen=True)
class Candidates:
    """The lanes near each fix that agree with its heading (rows by fix), with their emissions."""

    fix: np.ndarray
    xy: np.ndarray
    lane: np.ndarray
    pos_m: np.ndarray
    distance_m: np.ndarray
    emission: np.ndarray

    def rows(self, selected: np.ndarray) -> Candidates:
        """The candidates of the rows ``selected`` (a mask or indices)."""
        return Candidates(*(column[selected] for column in vars(self).values()))


@dataclass(frozen=True)
class Step:
    """One forward step: each candidate's normalised log-probability, best previous candidate (row of
    :class:`Previous`, -1: none) and route distance from it; per fix its best candidate (-1: none) and
    whether the step continued its sequence."""

    candidates: Candidates
    log_p: np.ndarray
    back: np.ndarray
    route_m: np.ndarray
    best: np.ndarray
    linked: np.ndarray


def _group_starts(group: np.ndarray) -> np.ndarray:
    """The first row of each run of equal values of a sorted ``group``."""
    if not group.size:
        return np.zeros(0, dtype=np.intp)
    return np.concatenate(([True], group[1:] != group[:-1])).nonzero()[0]


def _per_fix_max(values: np.ndarray, fix: np.ndarray, count: int) -> np.ndarray:
    """The greatest of ``values`` of each fix (rows sorted by ``fix``), -inf for a fix without rows."""
    result = np.full(count, -np.inf)
    starts = _group_starts(fix)
    if starts.size:
        result[fix[starts]] = np.maximum.reduceat(values, starts)
    return result


def _first_where(mask: np.ndarray, group: np.ndarray, count: int) -> np.ndarray:
    """Per group (rows sorted by ``group``), the first row where ``mask`` holds, -1 where none does."""
    result = np.full(count, -1, dtype=np.intp)
    rows = mask.nonzero()[0]
    firsts = rows[_group_starts(group[rows])]
    result[group[firsts]] = firsts
    return result


def _best_transitions(
    candidates: Candidates,
    previous: Previous,
    graph: LaneGraph,
    settings: MatchSettings,
    beta_m: np.ndarray,
    standing: np.ndarray,
    best: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """Each candidate's best score over the transitions from its fix's previous candidates (their log-probability
    plus the transition's), the previous candidate it comes from and the route distance from there, filled into
    ``best`` (score, previous row, route m) where a transition is possible."""
    best_score, back, best_route_m = best
    reps = previous.count[candidates.fix]
    first_pair = np.cumsum(reps) - reps
    pair_candidate = np.repeat(np.arange(len(reps)), reps)
    pair_fix = candidates.fix[pair_candidate]
    pair_previous = (previous.start[candidates.fix] - first_pair)[pair_candidate] + np.arange(pair_candidate.size)
    from_lane, to_lane = previous.lane[pair_previous], candidates.lane[pair_candidate]
    route_m = graph.route_m(from_lane, previous.pos_m[pair_previous], to_lane, candidates.pos_m[pair_candidate])
    straight_m = np.hypot(*(candidates.xy[pair_candidate] - previous.xy[pair_fix]).T)
    same_edge = graph.lane_edge[from_lane] == graph.lane_edge[to_lane]
    lane_change = graph.changes_lane(from_lane, to_lane)
    transition = -np.abs(route_m - straight_m) / beta_m[pair_fix]
    transition += np.where(lane_change, settings.lane_change_log_p, 0.0)
    transition += np.where(~same_edge & standing[pair_fix], settings.standstill_edge_log_p, 0.0)
    score = np.where(np.isnan(transition), -np.inf, previous.log_p[pair_previous] + transition)
    paired = (reps > 0).nonzero()[0]
    if paired.size:
        best_score[paired] = np.maximum.reduceat(score, first_pair[paired])
        at_best = (score == best_score[pair_candidate]) & np.isfinite(score)
        first = _first_where(at_best, pair_candidate, len(reps))
        found = first >= 0
        back[found] = pair_previous[first[found]]
        best_route_m[found] = route_m[first[found]]


def forward_step(
    candidates: Candidates,
    previous: Previous,
    count: int,
    graph: LaneGraph,
    settings: MatchSettings,
    beta_m: np.ndarray,
    standing: np.ndarray,
) -> Step:
    """The forward (Viterbi) step: each candidate's best transition from the previous candidates of its
    fix plus its emission, normalised per fix; a fix none of whose candidates is reached from its
    previous ones starts afresh from the emissions. ``beta_m`` is each fix's transition scale, m;
    ``standing`` whether each fix's vehicle stood still since its previous fix (moving on to another
    edge then costs :attr:`MatchSettings.standstill_edge_log_p`)."""
    reps = previous.count[candidates.fix]
    best_score = np.full(len(reps), -np.inf)
    back = np.full(len(reps), -1, dtype=np.intp)
    best_route_m = np.full(len(reps), np.nan)
    if previous.fix.size:  # else no vehicle continues a sequence: every fix starts afresh
        _best_transitions(candidates, previous, graph, settings, beta_m, standing, (best_score, back, best_route_m))
    linked = np.zeros(count, dtype=bool)
    linked[candidates.fix[np.isfinite(best_score)]] = True
    total = candidates.emission + np.where(linked[candidates.fix], best_score, 0.0)
    log_p = total - _per_fix_max(total, candidates.fix, count)[candidates.fix]
    best = _first_where(log_p == 0.0, candidates.fix, count)
    back[~linked[candidates.fix]] = -1
    return Step(candidates, log_p, back, best_route_m, best, linked)


def kept_rows(step: Step, count: int, lane_map: np.ndarray, max_candidates: int) -> tuple[np.ndarray, np.ndarray]:
    """The candidate rows each fix keeps for its next fix: those on its best candidate's map that are
    still possible, most probable first, at most ``max_candidates``; as rows
    grouped by fix and the bounds of each fix's group (``rows[bounds[i]:bounds[i + 1]]``)."""
    candidates = step.candidates
    best_map = np.full(count, -1, dtype=np.intp)
    has = step.best >= 0
    best_map[has] = lane_map[candidates.lane[step.best[has]]]
    possible = np.isfinite(step.log_p) & (lane_map[candidates.lane] == best_map[candidates.fix])
    rows = possible.nonzero()[0]
    rows = rows[np.lexsort((-step.log_p[rows], candidates.fix[rows]))]
    fix = candidates.fix[rows]
    rank = np.arange(rows.size) - fix.searchsorted(fix)
    rows = rows[rank < max_candidates]
    return rows, candidates.fix[rows].searchsorted(np.arange(count + 1))


def viterbi_path(steps: list[tuple[Step, np.ndarray]]) -> list[int]:
    """The candidate row of each step of one vehicle's trace (its step and kept rows, in time order) on the
    most probable path: from the last matched fix back along the best transitions, afresh from the best
    candidate where a step started afresh; -1 for a step that matched nothing."""
    chosen = [-1] * len(steps)
    matched = [k for k, (step, _kept) in enumerate(steps) if step.best[0] >= 0]
    following = -1  # the row the later matched step's candidate came from; -1: take the step's best
    for position in range(len(matched) - 1, -1, -1):
        step = steps[matched[position]][0]
        chosen[matched[position]] = row = int(step.best[0]) if following < 0 else following
        back = int(step.back[row])
        following = int(steps[matched[position - 1]][1][back]) if back >= 0 and position > 0 else -1
    return chosen
