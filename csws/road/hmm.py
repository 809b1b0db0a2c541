"""Matches the GNSS fixes of vehicles over their sequence: an online hidden-Markov map matcher.

Fleet telematics sends a fix a second or slower with metres of noise; matched one by one,
a fix inside a junction lands as often on a connection into a side street as on the one the
vehicle takes. Matched over the sequence (Newson & Krumm 2009, "Hidden Markov map matching
through noise and sparseness", as Valhalla's Meili and OSRM's matcher do):

* the **candidates** of a fix are the lanes within a radius of it (``search_sigmas`` times its
  accuracy, never under the tolerance) whose direction agrees with its heading;
* the **emission** of a candidate is a Gaussian of its distance from the fix with the fix's
  accuracy (``accuracy_m``, per fix or the default) and of its direction against the heading;
* the **transition** from a candidate of the previous fix is an exponential of
  |route distance between them - straight distance between the fixes| (Newson & Krumm's beta,
  widened by the fix's noise: :func:`transition_scale_m`), the route distance taken on the lane
  graph (:class:`csws.road.lanegraph.LaneGraph`); changing lanes costs a fixed log-probability (to
  another lane of the same edge, or across a junction onto a lane the vehicle's own lane does not
  lead to: :meth:`LaneGraph.changes_lane`), so one noisy fix does not move the vehicle to the
  neighbouring lane.

Online, each vehicle keeps its candidates and their log-probabilities between fixes
(:class:`MatchState`, a few hundred bytes, stored with its session); each fix is one
forward (Viterbi) step for all vehicles of a batch at once, in numpy. The matched lane is the
most probable candidate, with one exception at junctions: a fix that could be on several
junction connections commits to a turn off the road only once the connections into that turn's
road hold :attr:`MatchSettings.commit_share` of the probability of all its candidate connections
(from any incoming edge: in a cluster of junctions metres apart, the next junction's connection is
a rival too); until then the fix is reported on the road's own continuation (:attr:`Placed.DEFERRED`), so
the path ahead follows the road, never a guessed turn; so is a fix whose best candidate is the very start of
a turn (the point every connection from the incoming lane starts at). A later fix on the side street decides.

A fix that matches no lane is placed by dead reckoning along the road from the last match
(:attr:`Placed.DEAD_RECKONED`, up to :attr:`MatchSettings.dead_reckoning_s`); a jump beyond
the graph's reach starts the sequence afresh. :meth:`SequenceMatcher.match_trace` matches a whole
trace with the same steps and a Viterbi backtrace: each fix on the path the later fixes confirm
(all of them, or the next ``lag``: what a matcher that waits that many fixes would answer). Online,
each fix's answer carries the window of one fix: the vehicle's last matched fix placed on the path the
new fix confirms (:class:`Confirmed`), so a fix in a junction is on the connection taken as soon as the
next fix shows it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import cast

import numpy as np

from csws.geometry import wrap_angle_rad
from csws.road.fixes import (
    Confirmed,
    Fixes,
    MatchState,
    Placed,
    SequenceMatches,
    Track,
    last_times_s,
    repeats,
    subset,
    with_repeats,
)
from csws.road.lanegraph import LaneGraph
from csws.road.lanes_shown import LaneHistory, lanes_shown
from csws.road.match_settings import DEFAULT_MATCH_SETTINGS, MatchSettings
from csws.road.matching import MapMatcher, compass_to_math_rad, lane_point
from csws.road.roadmap import RoadMap
from csws.road.viterbi import Candidates, Previous, Step, forward_step, kept_rows, viterbi_path
from csws.state import overtaken

__all__ = [
    "MatchState",
    "Track",
    "Fixes",
    "Placed",
    "Confirmed",
    "SequenceMatches",
    "SequenceMatcher",
    "transition_scale_m",
]  # the first six from csws.road.fixes


def transition_scale_m(beta_m: float, sigma_m: np.ndarray) -> np.ndarray:
    """Each fix's transition scale: Newson & Krumm's beta (how far the route between exact positions departs
    from the straight line) widened by the fixes' noise, sqrt(beta^2 + sigma^2), m.

    The straight distance between two fixes is off by the difference of their errors along the way, of
    standard deviation sqrt(2) sigma (both fixes taken at this one's ``sigma_m``); the exponential of
    |difference| with scale b has standard deviation sqrt(2) b, so the two together have the standard
    deviation of one with scale sqrt(beta^2 + sigma^2). With a fixed beta a noisy fix's honest route counts
    as improbable as a wrong road's: at 1 Hz and sigma 8 m, one fix in eleven left the road the vehicle drove.
    """
    return np.hypot(beta_m, sigma_m)


class SequenceMatcher:
    """Matches the fixes of vehicles over their sequence on one or more road maps.

    Parameters
    ----------
    road_maps
        The maps, in order of preference (their lanes numbered as :class:`MapMatcher` numbers them).
    settings
        Tolerances and the model's scales.
    """

    def __init__(self, road_maps: Sequence[RoadMap], settings: MatchSettings = DEFAULT_MATCH_SETTINGS) -> None:
        self.index = MapMatcher(road_maps, settings)
        self.road_maps = self.index.road_maps
        self.settings = settings
        self.graph = LaneGraph(self.road_maps, settings.reach_m)
        #: Each map's lanes by id, numbered over all maps.
        self._numbers = [
            {lane_id: self.index.lane_number(map_index, lane_id) for lane_id in road_map.lane_ids}
            for map_index, road_map in enumerate(self.road_maps)
        ]
        self._heading_tolerance_rad = math.radians(settings.heading_tolerance_deg)
        self._heading_sigma_rad = math.radians(settings.heading_sigma_deg)

    def match(self, fixes: Fixes, tracks: Sequence[Track | None]) -> SequenceMatches:
        """Place one fix of each of many distinct vehicles, each continuing its ``tracks`` entry
        (None for a vehicle seen first, or whose sequence is lost).

        A fix that repeats its vehicle's last matched fix (the same time and place: a resent
        message) brings nothing new: it is placed where that one was, and the track is kept. A fix
        taken before that one, by at most :data:`csws.state.CLOCK_JUMP_S` (a message that came late,
        behind a newer one; the engine answers it as stale), is placed by itself, as a vehicle's first
        fix is, and the track is kept too: the sequence, and dead reckoning from it, go on from the
        newest fix. Further back, the vehicle's clock started again: the fix continues the track.
        """
        last_time_s = last_times_s(tracks)
        repeated = repeats(fixes, tracks, last_time_s)
        late = overtaken(last_time_s, fixes.time_s)
        if not repeated.any() and not late.any():
            return self._advance(fixes, tracks)[0]
        fresh = (~repeated).nonzero()[0]
        if not fresh.size:
            return with_repeats(None, fresh, tracks, late)
        continued = [None if late[row] else tracks[row] for row in fresh.tolist()]
        matches = self._advance(subset(fixes, fresh), continued)[0]
        return with_repeats(matches, fresh, tracks, late)

    def match_trace(self, fixes: Fixes, track: Track | None = None, lag: int | None = None) -> SequenceMatches:
        """Place the fixes of one vehicle, in time order, each on the path the fixes up to ``lag`` after it
        make most probable (the Viterbi path: a fix in a junction on the connection the later fixes show);
        ``lag`` None takes the whole trace, 1 what the fix after it decides.

        Raises
        ------
        ValueError
            If ``lag`` is negative.
        """
        if lag is not None and lag < 0:
            raise ValueError(f"lag must be a number of fixes, 0 or more, got {lag!r}")
        answers, steps = [], []
        for row in range(fixes.probes.count):
            matches, step, kept = self._advance(subset(fixes, np.array([row])), [track])
            answers.append(matches)
            steps.append((step, kept[0]))
            track = matches.tracks[0]
        lane_id = [matches.lane_id[0] for matches in answers]
        map_index = np.array([matches.map_index[0] for matches in answers], dtype=np.intp)
        pos_m = np.array([matches.lane_pos_m[0] for matches in answers])
        distance_m = np.array([matches.distance_m[0] for matches in answers])
        placed = [matches.placed[0] for matches in answers]
        chosen = (
            viterbi_path(steps) if lag is None else [viterbi_path(steps[k : k + lag + 1])[0] for k in range(len(steps))]
        )
        for k, row in enumerate(chosen):
            if row >= 0:
                candidates = steps[k][0].candidates
                map_index[k], lane_id[k] = self.index.lane_name(int(candidates.lane[row]))
                pos_m[k], distance_m[k] = candidates.pos_m[row], candidates.distance_m[row]
                placed[k] = Placed.MATCHED
        reason = [matches.reason[0] for matches in answers]
        confirmed = [matches.confirmed[0] for matches in answers]
        return SequenceMatches(map_index, lane_id, pos_m, distance_m, placed, reason, [track], confirmed)

    # ------------------------------------------------------------------ one step
    def _advance(
        self, fixes: Fixes, tracks: Sequence[Track | None]
    ) -> tuple[SequenceMatches, Step, tuple[np.ndarray, np.ndarray]]:
        """One forward step for every fix: the matches, the step and each fix's kept candidate rows."""
        count = fixes.probes.count
        sigma_m = np.where(np.isfinite(fixes.accuracy_m), fixes.accuracy_m, self.settings.accuracy_m)
        radius_m = np.maximum(self.settings.tolerance_m, self.settings.search_sigmas * sigma_m)
        with np.errstate(invalid="ignore"):  # a speed not given (NaN) is not slow
            slow = fixes.speed_mps < self.settings.standstill_mps
        candidates, near = self._candidates(fixes, sigma_m, radius_m, slow)
        previous = self._previous(tracks, count)
        beta_m = transition_scale_m(self.settings.transition_beta_m, sigma_m)
        step = forward_step(
            candidates, previous, count, self.graph, self.settings, beta_m, self._standing(slow, previous)
        )
        kept = kept_rows(step, count, self.index.lane_map, self.settings.max_candidates)
        lane, pos_m, distance_m, placed = self._reported(step, count)
        self._dead_reckon(fixes, tracks, lane, pos_m, distance_m, placed)
        some_lane = np.maximum(lane, 0)  # a lane for every fix, read only where one was placed
        lane_ids: list[str | None] = self.index.lane_ids[some_lane].tolist()
        new_tracks = self._tracks(fixes, step, kept, previous, tracks, (lane_ids, pos_m, distance_m, placed))
        placed_anywhere = lane >= 0
        reason: list[str | None] = [None] * count
        for fix in (~placed_anywhere).nonzero()[0].tolist():
            lane_ids[fix] = None
            reason[fix] = self._reason(bool(near[fix]), float(radius_m[fix]), float(fixes.heading_deg[fix]))
        matches = SequenceMatches(
            np.where(placed_anywhere, self.index.lane_map[some_lane], -1),
            lane_ids,
            pos_m,
            distance_m,
            placed,
            reason,
            new_tracks,
            self._confirmed(step, previous, tracks),
        )
        return matches, step, kept

    def _candidates(
        self, fixes: Fixes, sigma_m: np.ndarray, radius_m: np.ndarray, slow: np.ndarray
    ) -> tuple[Candidates, np.ndarray]:
        """The lanes near each fix agreeing with its heading, with their emission log-probabilities,
        and whether any lane at all was near each fix (``slow``: whether each fix gives a speed under
        :attr:`MatchSettings.standstill_mps`)."""
        probes = fixes.probes
        found = self.index.nearby(probes, radius_m) if len(probes.fix) else None
        if found is None or not len(found):
            empty = np.zeros(0)
            return Candidates(
                empty.astype(np.intp), np.zeros((0, 2)), empty.astype(np.intp), empty, empty, empty
            ), np.zeros(probes.count, dtype=bool)
        fix = probes.fix[found.point_index]
        near = np.bincount(fix, minlength=probes.count) > 0
        off_rad = wrap_angle_rad(found.heading_rad - compass_to_math_rad(fixes.heading_deg[fix]))
        agrees = ~(np.abs(off_rad) > self._heading_tolerance_rad)  # a NaN heading agrees
        heading_term = np.where(np.isnan(off_rad), 0.0, off_rad / self._heading_sigma_rad)
        emission = -0.5 * ((found.distance_m / sigma_m[fix]) ** 2 + heading_term**2)
        emission += np.where(
            slow[fix] & self.graph.internal[found.lane_index], self.settings.standstill_junction_log_p, 0.0
        )
        order = np.argsort(fix, kind="stable")
        order = order[agrees[order]]
        candidates = Candidates(
            fix[order],
            probes.xy[found.point_index[order]],
            found.lane_index[order].astype(np.intp),
            found.lane_pos_m[order],
            found.distance_m[order],
            emission[order],
        )
        return candidates, near

    def _previous(self, tracks: Sequence[Track | None], count: int) -> Previous:
        """The candidates of the vehicles' previous fixes, their lanes numbered over all maps (a lane the maps
        no longer have is dropped)."""
        rows: list[int] = []
        sizes: list[int] = []
        lanes: list[int] = []
        pos_m: list[float] = []
        log_p: list[float] = []
        places: list[tuple[float, float, float, float]] = []  # x, y, time, speed
        for row, track in enumerate(tracks):
            if track is not None:
                state, by_id = track.state, self._numbers[track.map_index]
                rows.append(row)
                sizes.append(len(state.candidates))
                lanes += [by_id.get(lane_id, -1) for lane_id in state.candidates]
                pos_m += state.candidate_pos_m
                log_p += state.log_p
                places.append((state.x_m, state.y_m, state.time_s, state.speed_mps))
        lane = np.array(lanes, dtype=np.intp)
        known = lane >= 0
        fix = np.repeat(np.array(rows, dtype=np.intp), sizes)[known]
        columns = np.full((count, 4), np.nan)
        if rows:
            columns[rows] = places
        counts = np.bincount(fix, minlength=count)
        starts = np.cumsum(counts) - counts
        return Previous(
            fix,
            lane[known],
            np.array(pos_m, dtype=float)[known],
            np.array(log_p, dtype=float)[known],
            starts,
            counts,
            columns[:, :2],
            columns[:, 2],
            columns[:, 3],
        )

    def _standing(self, slow: np.ndarray, previous: Previous) -> np.ndarray:
        """Whether each fix's vehicle stood still since its previous fix: the fix gives a speed, and it and
        the previous one are both under :attr:`MatchSettings.standstill_mps` (``slow``: the fix's is; a
        vehicle waiting at a stop line, its fixes scattered into the junction by the noise, has not entered it)."""
        with np.errstate(invalid="ignore"):
            return slow & (previous.speed_mps < self.settings.standstill_mps)

    # ------------------------------------------------------------------ what is reported
    def _confirmed(self, step: Step, previous: Previous, tracks: Sequence[Track | None]) -> list[Confirmed | None]:
        """Each vehicle's last matched fix as its new fix confirms it: the candidate its most probable
        candidate came from (the Viterbi path over the two fixes: the matcher's window of one fix)."""
        confirmed: list[Confirmed | None] = [None] * len(tracks)
        has = (step.best >= 0).nonzero()[0]
        came_from = step.back[step.best[has]]
        linked = came_from >= 0
        rows = came_from[linked]
        for fix, lane, pos_m in zip(
            has[linked].tolist(), previous.lane[rows].tolist(), previous.pos_m[rows].tolist(), strict=True
        ):
            state = cast(Track, tracks[fix]).state  # a candidate came from its previous fix: it has a track
            map_index, lane_id = self.index.lane_name(lane)
            confirmed[fix] = Confirmed(state.time_s, map_index, lane_id, pos_m, lane_id != state.lane_id)
        return confirmed

    def _reported(self, step: Step, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[Placed | None]]:
        """Each fix's reported lane (-1: none), lane position and distance, and how it was placed: its best
        candidate, or, inside a junction whose turn is not yet decided, the road's continuation."""
        candidates, best = step.candidates, step.best
        has = best >= 0
        lane = np.full(count, -1, dtype=np.intp)
        pos_m, distance_m = np.full(count, np.nan), np.full(count, np.nan)
        chosen = best[has]
        lane[has], pos_m[has], distance_m[has] = (
            candidates.lane[chosen],
            candidates.pos_m[chosen],
            candidates.distance_m[chosen],
        )
        placed: list[Placed | None] = [Placed.MATCHED if h else None for h in has.tolist()]
        for fix in self._undecided(step, count).nonzero()[0].tolist():
            lane[fix], pos_m[fix], distance_m[fix] = self._continuation(step, fix)
            placed[fix] = Placed.DEFERRED
        return lane, pos_m, distance_m, placed

    def _undecided(self, step: Step, count: int) -> np.ndarray:
        """Which fixes' best candidate turns off the road inside a junction while the connections into its
        road hold less than :attr:`MatchSettings.commit_share` of all its candidate connections, or lies at
        the very start of its connection's first internal lane (a fix level with or behind it, its projection
        clamped there): that point is the end of the lane the connection comes from, where every connection from
        it starts, so it is no evidence for this one's turn. The start of a later internal lane of a connection
        (SUMO splits a left turn where its vehicles wait for a gap) is inside the turn, and is not such a point."""
        candidates, graph = step.candidates, self.graph
        has = step.best >= 0
        has_lane = candidates.lane[step.best[has]]
        has_turning = graph.turns[has_lane] & (graph.entry_lane[has_lane] >= 0)
        turning = np.zeros(count, dtype=bool)
        if not has_turning.any():
            return turning
        turning[has] = has_turning
        best_lane = np.zeros(count, dtype=np.intp)
        best_lane[has] = has_lane
        lane, fix = candidates.lane, candidates.fix
        probability = np.exp(step.log_p)
        group = graph.internal[lane] & turning[fix]
        best_exit = graph.exit_edge[best_lane][fix]
        same = group & (graph.exit_edge[lane] == best_exit) & (best_exit >= 0)
        group_p = np.bincount(fix, weights=probability * group, minlength=count)
        same_p = np.bincount(fix, weights=probability * same, minlength=count)
        at_start = np.zeros(count, dtype=bool)
        at_start[has] = (candidates.pos_m[step.best[has]] <= 0.0) & graph.connection_start[has_lane]
        return turning & ((same_p < self.settings.commit_share * group_p) | at_start)

    def _continuation(self, step: Step, fix: int) -> tuple[int, float, float]:
        """Where a fix whose turn is undecided is reported: on the lane the road continues on from the
        incoming lane if it is a candidate, else at the end of the incoming lane (lane, position, distance)."""
        candidates, graph = step.candidates, self.graph
        entry = int(graph.entry_lane[candidates.lane[step.best[fix]]])
        following = int(graph.continuation[entry])
        rows = ((candidates.fix == fix) & (candidates.lane == following)).nonzero()[0]
        if following >= 0 and rows.size:
            row = int(rows[0])
            return following, float(candidates.pos_m[row]), float(candidates.distance_m[row])
        end_m = float(graph.lane_length_m[entry])
        return entry, end_m, self._distance_to(entry, end_m, candidates.xy[step.best[fix]])

    def _distance_to(self, lane: int, lane_pos_m: float, xy: np.ndarray) -> float:
        """Distance from ``xy`` to a lane position, m."""
        map_index, lane_id = self.index.lane_name(lane)
        x, y = lane_point(self.road_maps[map_index], lane_id, lane_pos_m)
        return math.hypot(float(xy[0]) - x, float(xy[1]) - y)

    def _dead_reckon(
        self,
        fixes: Fixes,
        tracks: Sequence[Track | None],
        lane: np.ndarray,
        pos_m: np.ndarray,
        distance_m: np.ndarray,
        placed: list[Placed | None],
    ) -> None:
        """Place the fixes that matched no lane by dead reckoning from their vehicle's last match, within
        :attr:`MatchSettings.dead_reckoning_s` of it: on along the road at the fix's speed (else the
        last one), filled into the columns."""
        probes = fixes.probes
        for fix in (lane < 0).nonzero()[0].tolist():
            track = tracks[fix]
            if track is None:
                continue
            state = track.state
            elapsed_s = float(fixes.time_s[fix]) - state.time_s
            start = self.index.lane_number(track.map_index, state.lane_id)
            if start < 0 or not (0.0 <= elapsed_s <= self.settings.dead_reckoning_s):
                continue
            speed_mps = float(fixes.speed_mps[fix]) if math.isfinite(fixes.speed_mps[fix]) else state.speed_mps
            lane[fix], pos_m[fix] = self.graph.advance(start, state.lane_pos_m, speed_mps * elapsed_s)
            own = np.flatnonzero((probes.fix == fix) & ((probes.map_index < 0) | (probes.map_index == track.map_index)))
            distance_m[fix] = (
                self._distance_to(int(lane[fix]), float(pos_m[fix]), probes.xy[own[0]]) if own.size else np.nan
            )
            placed[fix] = Placed.DEAD_RECKONED

    def _tracks(
        self,
        fixes: Fixes,
        step: Step,
        kept: tuple[np.ndarray, np.ndarray],
        previous: Previous,
        tracks: Sequence[Track | None],
        reported: tuple[list[str | None], np.ndarray, np.ndarray, list[Placed | None]],
    ) -> list[Track | None]:
        """What each vehicle keeps for its next fix: the fix's kept candidates where it matched, else its
        previous track (``reported``: each fix's reported lane id, lane position, distance and placing)."""
        candidates, best = step.candidates, step.best
        rows, bounds = kept
        best_rows = np.where(best >= 0, best, 0) if len(candidates.lane) else np.zeros(len(best), dtype=np.intp)
        xy = candidates.xy[best_rows].tolist() if len(candidates.lane) else [(0.0, 0.0)] * len(best)
        map_index = self.index.lane_map[candidates.lane[best_rows]].tolist() if len(candidates.lane) else []
        names = self.index.lane_ids[candidates.lane[rows]].tolist()
        log_p, cand_pos_m = step.log_p[rows].tolist(), candidates.pos_m[rows].tolist()
        lane_ids, pos_m, distance_m, placed = reported
        was_shown = [track is not None and track.state.lane_shown for track in tracks]
        shown = lanes_shown(
            step, kept, previous, LaneHistory(placed, was_shown), self.graph, self.settings.commit_share
        ).tolist()
        columns = zip(
            (best >= 0).tolist(),
            bounds[:-1].tolist(),
            bounds[1:].tolist(),
            fixes.time_s.tolist(),
            xy,
            self._speeds_mps(fixes, step, previous, tracks).tolist(),
            lane_ids,
            pos_m.tolist(),
            distance_m.tolist(),
            placed,
            strict=True,
        )
        result = list(tracks)
        for fix, (is_matched, a, b, time_s, (x_m, y_m), speed_mps, lane_id, lane_pos_m, fix_m, how) in enumerate(
            columns
        ):
            if is_matched:
                state = MatchState(
                    time_s,
                    x_m,
                    y_m,
                    speed_mps,
                    lane_id,
                    lane_pos_m,
                    fix_m,
                    how,
                    tuple(names[a:b]),
                    tuple(cand_pos_m[a:b]),
                    tuple(log_p[a:b]),
                    shown[fix],
                )
                result[fix] = Track(map_index[fix], state)
        return result

    @staticmethod
    def _speeds_mps(fixes: Fixes, step: Step, previous: Previous, tracks: Sequence[Track | None]) -> np.ndarray:
        """Each vehicle's speed at its fix: given, else the route distance from its previous fix over the
        time between them, else its previous speed (0 for a new vehicle), m/s."""
        before = np.array([0.0 if track is None else track.state.speed_mps for track in tracks])
        route_m = np.full(len(before), np.nan)
        has = step.best >= 0
        route_m[has] = step.route_m[step.best[has]]
        elapsed_s = fixes.time_s - previous.time_s
        with np.errstate(invalid="ignore", divide="ignore"):
            estimated = np.where(elapsed_s > 0, np.maximum(route_m, 0.0) / elapsed_s, np.nan)
        estimated = np.where(np.isfinite(estimated), estimated, before)
        return np.where(np.isfinite(fixes.speed_mps), fixes.speed_mps, estimated)

    def _reason(self, near: bool, radius_m: float, heading_deg: float) -> str:
        """Why a fix was placed nowhere."""
        tolerance = f"{radius_m:g} m"
        if not near:
            return f"no lane within {tolerance}"
        return (
            f"no lane within {tolerance} runs within {self.settings.heading_tolerance_deg:g} deg"
            f" of the heading {heading_deg:g} deg"
        )
