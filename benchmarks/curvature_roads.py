"""The roads the curvature benchmark is run on, each built exactly with its truth (:mod:`benchmarks.curvature`).

A road is straight, arc, straight (:func:`arc_road`) or a straight alone (:func:`straight_road`),
built with :mod:`csws.geometry` so that its radius and the arc's start (3.4) are known, and drawn
in one of three ways: as a SUMO lane shape (:func:`dense_shape`), as a map way with nodes 5-30 m
apart and noise on every node (:func:`sparse_way`), or as such a way whose nodes follow an arc as
mappers draw it (:func:`mapped_way`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from csws.geometry import Piece, arc, piece_starts_s, pose_at, sample_pieces, straight

#: Warning radius used on the arc cases, so that every arc of R <= 500 m is a curve, m.
ARC_WARNING_RADIUS_M = 1000.0
DENSE_SPACING_M = (0.5, 1.0)
SPARSE_SPACING_M = (5.0, 30.0)
SPARSE_NOISE_RMS_M = 0.5
#: On mapped ways, the longest node gap on an arc as a fraction of its length and of its radius.
MAPPED_ARC_FRACTION = 1.0 / 3.0
MAPPED_RADIUS_FRACTION = 0.5
ROUNDING_M = 0.01


@dataclass(frozen=True)
class Road:
    """A constructed polyline with its truth: the arc's start and end, its radius and
    signed curvature, and where the road starts (the first node's true place) and heads."""

    xy: np.ndarray
    arc_start_s: float
    arc_end_s: float
    radius_m: float
    curvature: float
    origin_xy: tuple[float, float]
    heading: float


def _random_pose(rng: np.random.Generator) -> tuple[tuple[float, float], float]:
    """A random start point (network-sized coordinates) and heading."""
    return (float(rng.uniform(-5000, 5000)), float(rng.uniform(-5000, 5000))), float(rng.uniform(-np.pi, np.pi))


Pose = tuple[tuple[float, float], float]


def dense_shape(pieces: list[Piece], rng: np.random.Generator, pose: Pose | None = None) -> np.ndarray:
    """A SUMO-like lane shape: vertices 0.5-1 m apart, coordinates rounded to 1 cm, starting
    at ``pose`` (random if not given)."""
    start_xy, heading = pose or _random_pose(rng)
    xy, _ = sample_pieces(pieces, float(rng.uniform(*DENSE_SPACING_M)), start_xy, heading)
    return np.round(xy / ROUNDING_M) * ROUNDING_M


def _node_arc_lengths(pieces: list[Piece], rng: np.random.Generator, mapped: bool) -> np.ndarray:
    """Arc lengths of a way's nodes: gaps drawn from :data:`SPARSE_SPACING_M`; when
    ``mapped``, a gap that overlaps an arc is scaled down so that it is at most
    :data:`MAPPED_ARC_FRACTION` of the arc's length and :data:`MAPPED_RADIUS_FRACTION` of
    its radius."""
    starts = piece_starts_s(pieces)
    arcs = [(starts[i], starts[i + 1], piece) for i, piece in enumerate(pieces) if piece.curvature != 0]
    s = [0.0]
    while s[-1] < starts[-1]:
        gap = float(rng.uniform(*SPARSE_SPACING_M))
        for arc_start, arc_end, piece in arcs if mapped else ():
            if s[-1] < arc_end and s[-1] + gap > arc_start:
                longest_m = min(
                    SPARSE_SPACING_M[1], MAPPED_ARC_FRACTION * piece.length_m, MAPPED_RADIUS_FRACTION * piece.radius_m
                )
                gap *= longest_m / SPARSE_SPACING_M[1]
        s.append(s[-1] + gap)
    return np.append(np.array(s[:-1]), starts[-1])


def sparse_way(
    pieces: list[Piece], rng: np.random.Generator, pose: Pose | None = None, mapped: bool = False
) -> np.ndarray:
    """A map-like way: nodes at irregular arc lengths 5-30 m apart (closer on arcs when
    ``mapped``, see :func:`_node_arc_lengths`), 0.5 m RMS noise, starting at ``pose``."""
    start_xy, heading = pose or _random_pose(rng)
    s = _node_arc_lengths(pieces, rng, mapped)
    x, y, _ = pose_at(pieces, s, start_xy, heading)
    noise = rng.normal(0.0, SPARSE_NOISE_RMS_M / np.sqrt(2.0), size=(len(s), 2))
    return np.column_stack((x, y)) + noise


def mapped_way(pieces: list[Piece], rng: np.random.Generator, pose: Pose | None = None) -> np.ndarray:
    """A sparse way whose nodes follow mapping practice on arcs (:func:`sparse_way`)."""
    return sparse_way(pieces, rng, pose, mapped=True)


def arc_road(rng: np.random.Generator, shape: Callable[..., np.ndarray]) -> Road:
    """Straight, arc of R 25-500 m turning 20-120 degrees either way, straight."""
    radius_m = float(np.exp(rng.uniform(np.log(25.0), np.log(500.0))))
    before_m = float(rng.uniform(50, 150))
    pieces = [
        straight(before_m),
        arc(radius_m, float(rng.uniform(20, 120)), str(rng.choice(["left", "right"]))),
        straight(float(rng.uniform(50, 150))),
    ]
    pose = _random_pose(rng)
    return Road(shape(pieces, rng, pose), before_m, before_m + pieces[1].length_m, radius_m, pieces[1].curvature, *pose)


def straight_road(
    rng: np.random.Generator, shape: Callable[[list[Piece], np.random.Generator], np.ndarray]
) -> np.ndarray:
    """A straight of 200-1,000 m."""
    return shape([straight(float(rng.uniform(200, 1000)))], rng)
