"""Which lane of its edge a vehicle's fixes show: the lane its path ahead may start from.

The lanes of one edge lie some 3.2 m apart and a fleet's fixes are off by 3 to 8 m, so the lane a fix is
matched to is mostly a guess, and the path ahead of a fix starts from the lane of its edge that keeps the
road (:class:`csws.ahead.roadlane.RoadLanes`). Where the sequence of fixes does show the lane, as the
junction's commit rule asks of a turn (:attr:`csws.road.match_settings.MatchSettings.commit_share`), a
vehicle in an exit or turning lane can be warned of the curve beyond before it leaves the road. A fix
shows its lane when, placed on its best candidate, its candidates on that lane hold the commit share of
its candidates on the edge's lanes, with another lane of the edge among them (a fix so far off that no
neighbouring lane is a candidate shows nothing). The lane stays shown while the sequence goes on and each
later fix's best candidate comes from the previous fix's candidate on the same lane.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from csws.road.fixes import Placed
from csws.road.lanegraph import LaneGraph
from csws.road.viterbi import Previous, Step

__all__ = ["LaneHistory", "lanes_shown"]


@dataclass(frozen=True)
class LaneHistory:
    """How each fix of a step was placed, and whether its vehicle's previous fix showed its lane."""

    placed: Sequence[Placed | None]
    was_shown: Sequence[bool]


def lanes_shown(
    step: Step,
    kept: tuple[np.ndarray, np.ndarray],
    previous: Previous,
    history: LaneHistory,
    graph: LaneGraph,
    commit_share: float,
) -> np.ndarray:
    """Per fix of a matcher's step, whether the fixes show the lane it was matched to (see the module).

    Parameters
    ----------
    step, previous
        The forward step and the previous fixes' candidates it continued.
    kept
        The candidate rows each fix keeps, grouped by fix, and each group's bounds.
    history
        Each fix's placing and its previous fix's shown lane.
    graph
        The lane graph (lanes and edges numbered over all maps).
    commit_share
        The share of the edge's candidates the lane's must hold.
    """
    rows, bounds = kept
    count = len(bounds) - 1
    if not step.candidates.lane.size:  # no fix has a candidate
        return np.zeros(count, dtype=bool)
    placed_on_best = np.array([how is Placed.MATCHED for how in history.placed], dtype=bool) & (step.best >= 0)
    best_lane = step.candidates.lane[np.maximum(step.best, 0)]
    fix = np.repeat(np.arange(count), np.diff(bounds))
    lanes, lane_edge = step.candidates.lane[rows], graph.lane_edge
    on_edge = lane_edge[lanes] == lane_edge[best_lane[fix]]
    own = lanes == best_lane[fix]
    probability = np.exp(step.log_p[rows]) * on_edge
    edge_p = np.bincount(fix, weights=probability, minlength=count)
    lane_p = np.bincount(fix, weights=probability * own, minlength=count)
    beside = np.bincount(fix, weights=on_edge & ~own, minlength=count) > 0
    alone = graph.edge_lane_count[lane_edge[best_lane]] == 1
    held = (edge_p > 0) & (lane_p >= commit_share * edge_p) & (beside | alone)
    came_from = step.back[np.maximum(step.best, 0)]
    stayed = step.linked & (step.best >= 0) & (came_from >= 0) & np.asarray(history.was_shown, dtype=bool)
    stayed[stayed] = previous.lane[came_from[stayed]] == best_lane[stayed]
    return placed_on_best & (held | stayed)
