"""The scales of map matching: how far from a lane and off its direction a fix may be, and the
hidden-Markov model's weights (:mod:`csws.road.matching`, :mod:`csws.road.hmm`).

One frozen value holds them all, checked when made, so that a service's environment (``CSWS_MATCH_*``)
or a library caller sets them in one place and a bad value is refused with its name before any fix is
matched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["MatchSettings", "DEFAULT_MATCH_SETTINGS"]


@dataclass(frozen=True)
class MatchSettings:
    """How far from a lane and how far off its direction a fix may be.

    Attributes
    ----------
    tolerance_m
        A fix matches lanes within this distance, m (GNSS error plus map error).
    heading_tolerance_deg
        A fix with a heading matches only lanes whose direction differs from it by at
        most this, degrees: the opposite direction (180) and crossing roads (90) are out.
    continuation_links
        How many links ahead of the previous lane a lane still counts as its continuation.
    accuracy_m
        The standard deviation of a fix's position when the fix does not give its own
        (``accuracy_m``), m: the emission of the sequence matcher (:mod:`csws.road.hmm`) is a
        Gaussian of the distance from the lane with it (4.07 m in Newson & Krumm 2009).
    search_sigmas
        The sequence matcher looks for lanes within this many standard deviations of a fix's
        position, never nearer than ``tolerance_m``.
    heading_sigma_deg
        The standard deviation of a fix's heading against the lane's direction, degrees (GNSS heading
        noise and the angle of a lane change).
    transition_beta_m
        The scale of the exponential of |route distance - straight distance| between consecutive
        fixes, m (Newson & Krumm's beta).
    lane_change_log_p
        The log-probability of changing lanes between two fixes (within an edge, or across a junction onto
        a lane its own does not lead to): one noisy fix nearer the neighbouring lane does not move it there.
    commit_share
        Inside a junction, the matcher reports a turn off the road only once the connections into
        that turn's road hold this share of the probability of all the fix's candidate connections
        (of any junction); until then it reports the road's own continuation. A lane of an edge counts as
        shown once its candidates hold this share of those on the edge's lanes.
    standstill_mps
        A vehicle whose fix gives a speed under this, its previous fix's too, stood still between them, m/s.
    standstill_edge_log_p
        The log-probability that a vehicle standing still moved on to another edge between two fixes: a
        truck waiting at a stop line whose fixes scatter metres into the junction is still before it.
    standstill_junction_log_p
        The log-probability that a vehicle whose fix gives a speed under ``standstill_mps`` stands inside a
        junction rather than before it: vehicles wait at stop lines, seldom in the junction.
    dead_reckoning_s
        A fix that matches no lane is placed by dead reckoning along the road from the last
        match for up to this long after it, s; later it matches nothing.
    reach_m
        Route distances between candidates are known within this distance beyond an edge's end, m: a
        jump between fixes longer than this starts the sequence afresh.
    max_candidates
        The sequence matcher keeps at most this many candidate lanes of a vehicle between fixes.
    """

    tolerance_m: float = 10.0
    heading_tolerance_deg: float = 45.0
    continuation_links: int = 4
    accuracy_m: float = 4.0
    search_sigmas: float = 2.5
    heading_sigma_deg: float = 10.0
    transition_beta_m: float = 6.0
    lane_change_log_p: float = -1.5
    commit_share: float = 0.95
    standstill_mps: float = 1.0
    standstill_edge_log_p: float = -4.0
    standstill_junction_log_p: float = -4.0
    dead_reckoning_s: float = 10.0
    reach_m: float = 250.0
    max_candidates: int = 8

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance_m) and self.tolerance_m > 0):
            raise ValueError(f"tolerance_m must be a positive number of metres, got {self.tolerance_m!r}")
        if not (0 < self.heading_tolerance_deg <= 180):
            raise ValueError(f"heading_tolerance_deg must lie in (0, 180], got {self.heading_tolerance_deg!r}")
        if self.continuation_links < 0:
            raise ValueError(f"continuation_links must not be negative, got {self.continuation_links!r}")
        for name in ("accuracy_m", "search_sigmas", "heading_sigma_deg", "transition_beta_m", "reach_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        for name in ("lane_change_log_p", "standstill_edge_log_p", "standstill_junction_log_p"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value <= 0):
                raise ValueError(f"{name} must be a log-probability (<= 0), got {value!r}")
        if not (math.isfinite(self.standstill_mps) and self.standstill_mps >= 0):
            raise ValueError(f"standstill_mps must be a non-negative speed, got {self.standstill_mps!r}")
        if not (0.5 <= self.commit_share <= 1):
            raise ValueError(f"commit_share must lie in [0.5, 1], got {self.commit_share!r}")
        if not (math.isfinite(self.dead_reckoning_s) and self.dead_reckoning_s >= 0):
            raise ValueError(
                f"dead_reckoning_s must be a non-negative number of seconds, got {self.dead_reckoning_s!r}"
            )
        if self.max_candidates < 1:
            raise ValueError(f"max_candidates must be at least 1, got {self.max_candidates!r}")


#: The library's matching settings (frozen: one instance serves every matcher left to them).
DEFAULT_MATCH_SETTINGS = MatchSettings()
