"""How the lanes of a network are joined into road chains: which lane each continues on, where a chain is cut
on a straight, and the one polyline its lanes make (:mod:`csws.road.chains` fits and indexes them)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from csws.road.sharing import JOINT_TOLERANCE_M

__all__ = [
    "STRAIGHT_DEVIATION_M",
    "STRAIGHT_WINDOW_M",
    "cut_where_straight",
    "road_chains",
    "stitch",
    "stitch_vertices",
]

#: A road chain is cut at a joint where its polyline within this distance either side of the
#: joint lies within :data:`STRAIGHT_DEVIATION_M` of a line, m: no curve of the road (radius
#: at most R_c) runs through it, and each stretch is fitted on its own, which keeps the
#: polylines short (the sparse fit's cost grows faster than their length). A curve of
#: R 300 m deviates 2.7 m from the chord of such a window; one starting 30 m beyond the
#: joint still 0.17 m.
STRAIGHT_WINDOW_M = 40.0
#: See :data:`STRAIGHT_WINDOW_M`, m.
STRAIGHT_DEVIATION_M = 0.15


def stitch(shapes: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Join lane shapes in driving order into one polyline.

    A lane's first point is dropped when it repeats the previous lane's last point
    (within :data:`JOINT_TOLERANCE_M`), so the joint is one vertex and no zero-length
    segment is left to disturb the curvature.

    Returns
    -------
    xy
        The polyline, ``(n, 2)``.
    lane_start_s
        Arc length along it at each lane's first point, ``(len(shapes),)``.
    """
    xy, vertex_s, first_vertex = stitch_vertices(shapes)
    return xy, vertex_s[first_vertex]


def stitch_vertices(shapes: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """:func:`stitch`, with the arc length at every vertex of the polyline and the index of each lane's first vertex
    (a path's profile is read at every vertex)."""
    pieces = [shapes[0]]
    first_vertex = [0]
    vertex_count = len(shapes[0])
    gap = np.array([shape[0] for shape in shapes[1:]]).reshape(-1, 2)
    gap -= np.array([shape[-1] for shape in shapes[:-1]]).reshape(-1, 2)
    for shape, joined in zip(shapes[1:], (np.hypot(gap[:, 0], gap[:, 1]) <= JOINT_TOLERANCE_M).tolist(), strict=True):
        pieces.append(shape[1:] if joined else shape)
        first_vertex.append(vertex_count - 1 if joined else vertex_count)
        vertex_count += len(pieces[-1])
    xy = np.concatenate(pieces)
    vertex_s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    return xy, vertex_s, first_vertex


def road_chains(continues_into: np.ndarray) -> list[np.ndarray]:
    """The lanes of a network grouped into road chains, each in driving order.

    ``continues_into[i]`` is the lane lane ``i``'s road continues on (-1: none). Where
    several lanes continue into one, the first of them keeps it and the others end
    their chains there. A chain starts at a lane no other continues into; lanes left
    over lie on a loop (a ring road), which is cut at its lowest-numbered lane.
    """
    following = np.asarray(continues_into, dtype=np.int64).copy()
    has_predecessor = np.zeros(len(following), dtype=bool)
    for lane, nxt in enumerate(following.tolist()):
        if nxt >= 0:
            if has_predecessor[nxt]:
                following[lane] = -1
            has_predecessor[nxt] = True
    chains: list[np.ndarray] = []
    placed = np.zeros(len(following), dtype=bool)
    starts = np.flatnonzero(~has_predecessor).tolist() + list(range(len(following)))
    for start in starts:
        if placed[start]:
            continue
        members = [start]
        placed[start] = True
        while following[members[-1]] >= 0 and not placed[following[members[-1]]]:
            members.append(int(following[members[-1]]))
            placed[members[-1]] = True
        chains.append(np.array(members, dtype=np.int64))
    return chains


def _straight_joints(xy: np.ndarray, joint_s: np.ndarray) -> np.ndarray:
    """Which joints of a stitched chain lie on a straight stretch (:data:`STRAIGHT_WINDOW_M`)."""
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    straight = np.zeros(len(joint_s), dtype=bool)
    for index, at_s in enumerate(joint_s.tolist()):
        window = xy[(s >= at_s - STRAIGHT_WINDOW_M) & (s <= at_s + STRAIGHT_WINDOW_M)]
        chord = window[-1] - window[0]
        length = float(np.hypot(*chord))
        if length <= 0:
            continue
        relative = window - window[0]
        offset = np.abs(chord[0] * relative[:, 1] - chord[1] * relative[:, 0]) / length
        straight[index] = bool(offset.max() <= STRAIGHT_DEVIATION_M)
    return straight


def cut_where_straight(members: np.ndarray, road_shapes: Sequence[np.ndarray]) -> list[np.ndarray]:
    """A chain's lanes cut into stretches at the joints no curve runs through (:func:`_straight_joints`)."""
    if len(members) < 2:
        return [members]
    xy, start_s = stitch([road_shapes[lane] for lane in members.tolist()])
    cuts = np.flatnonzero(_straight_joints(xy, start_s[1:])) + 1
    return np.split(members, cuts)
