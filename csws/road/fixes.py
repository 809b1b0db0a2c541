"""GNSS fixes as the sequence matcher (:mod:`csws.road.hmm`) takes them, and what it answers and keeps of them.

:class:`Fixes` are one fix of each of many vehicles as columns; :class:`SequenceMatches` where each
was placed and how (:class:`Placed`); :class:`Track` what a vehicle keeps for its next fix, its
:class:`MatchState` a small MessagePack array stored with its session. A fix that repeats its
vehicle's last matched fix (a resent message) is answered from the track (:func:`repeats`,
:func:`with_repeats`); one taken before it (a late message) is placed by itself and leaves the track as it was.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import NamedTuple

import msgspec
import numpy as np

from csws.road.matching import Probes

__all__ = [
    "Placed",
    "MatchState",
    "Track",
    "Fixes",
    "Confirmed",
    "SequenceMatches",
    "subset",
    "last_times_s",
    "repeats",
    "with_repeats",
]


class Placed(StrEnum):
    """How a fix was placed on its lane."""

    #: On the most probable candidate.
    MATCHED = "matched"
    #: Inside a junction, on the road's continuation: the turn it may be taking is not yet shown.
    DEFERRED = "deferred"
    #: Matching no lane, moved on along the road from the last match.
    DEAD_RECKONED = "dead_reckoned"


class MatchState(msgspec.Struct, array_like=True, frozen=True, gc=False):
    """What the matcher keeps of a vehicle between fixes (a MessagePack array of some 100 bytes).

    Attributes
    ----------
    time_s
        When its last matched fix was taken, s.
    x_m, y_m
        Where that fix was, in the coordinates of the map of its lanes, m.
    speed_mps
        Its speed then, given or estimated, m/s (dead reckoning goes on with it).
    lane_id, lane_pos_m, distance_m, placed
        Where and how that fix was placed (dead reckoning starts there; the same fix sent again is
        placed there again), and its distance from there, m.
    candidates, candidate_pos_m, log_p
        The candidate lanes of that fix, their lane positions (m) and log-probabilities (the best 0).
    lane_shown
        Whether the fixes show that lane among the lanes of its edge, so that the path ahead may start from it
        (a turning lane, an exit lane): the fix was matched there and its candidates on the lane hold the commit
        share of those on the edge's lanes (:attr:`csws.road.match_settings.MatchSettings.commit_share`), or the
        previous fix's lane was shown and this one is on it still.
    """

    time_s: float
    x_m: float
    y_m: float
    speed_mps: float
    lane_id: str
    lane_pos_m: float
    distance_m: float
    placed: Placed
    candidates: tuple[str, ...]
    candidate_pos_m: tuple[float, ...]
    log_p: tuple[float, ...]
    lane_shown: bool = False


class Track(msgspec.Struct, frozen=True, gc=False):
    """A vehicle's matching state on one of the matched maps (by index)."""

    map_index: int
    state: MatchState


@dataclass(frozen=True)
class Fixes:
    """One fix of each of ``probes.count`` distinct vehicles, as columns.

    Attributes
    ----------
    probes
        Where to look for each fix (:class:`csws.road.matching.Probes`).
    time_s
        When each was taken, s.
    heading_deg, speed_mps, accuracy_m
        GNSS heading (degrees clockwise from north), speed (m/s) and position accuracy (one standard
        deviation, m); NaN where not given.
    """

    probes: Probes
    time_s: np.ndarray
    heading_deg: np.ndarray
    speed_mps: np.ndarray
    accuracy_m: np.ndarray

    @classmethod
    def of(
        cls,
        probes: Probes,
        time_s: Sequence[float] | np.ndarray,
        heading_deg: Sequence[float] | np.ndarray | None = None,
        speed_mps: Sequence[float] | np.ndarray | None = None,
        accuracy_m: Sequence[float] | np.ndarray | None = None,
    ) -> Fixes:
        """The fixes with NaN (not given) for each column left out."""

        def column(values: Sequence[float] | np.ndarray | None) -> np.ndarray:
            """The values as floats, NaN for each fix where none are given."""
            return np.full(probes.count, np.nan) if values is None else np.asarray(values, dtype=float)

        return cls(probes, column(time_s), column(heading_deg), column(speed_mps), column(accuracy_m))


class Confirmed(NamedTuple):
    """A vehicle's last matched fix as its new fix confirms it: the matcher's window of one fix.

    The forward step picks the new fix's most probable candidate together with the candidate of the
    last fix it came from (the Viterbi path over the two, Newson & Krumm 2009): a fix inside a
    junction, answered on the road's continuation while its turn was not shown, lies on the
    connection the vehicle took once the next fix is on the side street.

    Attributes
    ----------
    time_s
        When that fix was taken, s.
    map_index, lane_id, lane_pos_m
        Where it lies on the path the new fix makes most probable: map, lane and lane position, m.
    revised
        Whether that lane is not the one the fix was answered with.
    """

    time_s: float
    map_index: int
    lane_id: str
    lane_pos_m: float
    revised: bool


@dataclass(frozen=True)
class SequenceMatches:
    """Where each of many fixes was placed, as columns (see :class:`csws.road.matching.FixMatches`).

    Attributes
    ----------
    map_index
        ``(k,)`` the map of the lane, -1 where the fix was placed nowhere.
    lane_id, lane_pos_m, distance_m
        The lane (None: nowhere), the lane position and the fix's distance from that point, m.
    placed
        How each was placed, None where nowhere.
    reason
        Why a fix was placed nowhere, else None.
    tracks
        What to keep of each vehicle for its next fix (its previous track where the fix matched
        nothing; None for a vehicle with none).
    confirmed
        Each vehicle's last matched fix as this one confirms it; None where this fix does not continue
        that fix's sequence (a first fix, one sent again, one matching nothing or starting afresh).
    """

    map_index: np.ndarray
    lane_id: list[str | None]
    lane_pos_m: np.ndarray
    distance_m: np.ndarray
    placed: list[Placed | None]
    reason: list[str | None]
    tracks: list[Track | None]
    confirmed: list[Confirmed | None]

    def __len__(self) -> int:
        return len(self.lane_id)


def subset(fixes: Fixes, rows: np.ndarray) -> Fixes:
    """The fixes ``rows`` (increasing) of ``fixes`` alone, renumbered from 0."""
    probes = fixes.probes
    number = np.full(probes.count, -1, dtype=np.intp)
    number[rows] = np.arange(rows.size)
    mine = number[probes.fix] >= 0
    subset = Probes(rows.size, number[probes.fix[mine]], probes.xy[mine], probes.map_index[mine])
    columns = (fixes.time_s, fixes.heading_deg, fixes.speed_mps, fixes.accuracy_m)
    return Fixes(subset, *(column[rows] for column in columns))


def last_times_s(tracks: Sequence[Track | None]) -> np.ndarray:
    """When each vehicle's last matched fix was taken, s (NaN without a track)."""
    return np.array([math.nan if t is None else t.state.time_s for t in tracks])


def repeats(fixes: Fixes, tracks: Sequence[Track | None], last_time_s: np.ndarray) -> np.ndarray:
    """Which fixes repeat their vehicle's last matched fix (taken at ``last_time_s``, :func:`last_times_s`): the
    same time, a probe at the same place on its map."""
    if not (fixes.time_s == last_time_s).any():  # the common case: every fix is new
        return np.zeros(fixes.probes.count, dtype=bool)
    states = [
        (math.nan, math.nan, math.nan, -2) if t is None else (t.state.time_s, t.state.x_m, t.state.y_m, t.map_index)
        for t in tracks
    ]
    time_s, x_m, y_m, map_index = (np.array(column) for column in zip(*states, strict=True))
    probes = fixes.probes
    on_map = (probes.map_index < 0) | (probes.map_index == map_index[probes.fix])
    same = on_map & (probes.xy[:, 0] == x_m[probes.fix]) & (probes.xy[:, 1] == y_m[probes.fix])
    return (np.bincount(probes.fix[same], minlength=probes.count) > 0) & (fixes.time_s == time_s)


def with_repeats(
    matches: SequenceMatches | None, fresh: np.ndarray, tracks: Sequence[Track | None], late: np.ndarray
) -> SequenceMatches:
    """The matches of all fixes: those of the ``fresh`` ones (None: there are none), the repeated ones where
    their track placed them; a ``late`` fix (taken before its vehicle's last matched one) keeps the track as it
    was, the sequence going on from the newest fix."""
    count = len(tracks)
    map_index = np.array([-1 if t is None else t.map_index for t in tracks], dtype=np.intp)
    lane_id: list[str | None] = [None if t is None else t.state.lane_id for t in tracks]
    pos_m = np.array([math.nan if t is None else t.state.lane_pos_m for t in tracks])
    distance_m = np.array([math.nan if t is None else t.state.distance_m for t in tracks])
    placed: list[Placed | None] = [None if t is None else t.state.placed for t in tracks]
    reason: list[str | None] = [None] * count
    kept = list(tracks)
    confirmed: list[Confirmed | None] = [None] * count
    if matches is None:
        return SequenceMatches(map_index, lane_id, pos_m, distance_m, placed, reason, kept, confirmed)
    map_index[fresh], pos_m[fresh], distance_m[fresh] = matches.map_index, matches.lane_pos_m, matches.distance_m
    for k, row in enumerate(fresh.tolist()):
        lane_id[row], placed[row], reason[row] = matches.lane_id[k], matches.placed[k], matches.reason[k]
        if not late[row]:
            kept[row], confirmed[row] = matches.tracks[k], matches.confirmed[k]
    return SequenceMatches(map_index, lane_id, pos_m, distance_m, placed, reason, kept, confirmed)
