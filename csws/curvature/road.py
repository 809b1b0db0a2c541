"""Fits the road (straights and arcs) to the nodes of sparse polylines in the plane: the second step.

The road is the maximum-likelihood one under isotropic node noise, found by Levenberg-Marquardt
steps for a batch of polylines and trial roads at once."""

from __future__ import annotations

from dataclasses import dataclass, fields, is_dataclass
from typing import Any

import numpy as np

from .knots import _chord_means_of_ramps, _SparseBatch

#: Levenberg-Marquardt iterations polishing a sparse polyline's road in the plane.
POLISH_ITERATIONS = 12
#: A polish step gaining less than this fraction of the sum of squares ends a trial's polish.
POLISH_TOLERANCE = 1e-3
#: Least Levenberg-Marquardt damping (relative to the normal equations' diagonal).
MIN_DAMPING = 1e-6
#: Levenberg-Marquardt damping at which a trial's polish ends (its steps keep failing).
MAX_DAMPING = 10.0
#: Newton steps projecting the nodes onto the road before the polish (each of its steps adds one).
PROJECTION_STEPS = 1
#: The longer multiples of each polish step tried beside it (:func:`_best_scaled_step`).
STEP_SCALES = (3.0, 10.0)
#: Shortest part the polish lets a knot make, m.
MIN_POLISHED_PART_M = 0.1


@dataclass(frozen=True)
class _Nodes:
    """The nodes of sparse polylines relative to each one's first: ``xy`` (complex) and
    ``s`` (arc length along the polyline), ``(polylines, nodes)``, padded; ``real`` says
    which are nodes."""

    xy: np.ndarray
    s: np.ndarray
    real: np.ndarray


def _padded_nodes(polylines: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> _Nodes:
    """The nodes of polylines given by all their chords' start arc lengths, lengths and headings."""
    size = max(len(start_s) for start_s, _, _ in polylines) + 1
    xy, s = np.zeros((len(polylines), size), dtype=complex), np.zeros((len(polylines), size))
    real = np.arange(size)[None, :] <= np.array([len(start_s) for start_s, _, _ in polylines])[:, None]
    for row, (start_s, length_m, heading) in enumerate(polylines):
        count = len(start_s)
        xy[row, 1 : count + 1] = np.cumsum(length_m * np.exp(1j * heading))
        s[row, : count + 1] = np.append(start_s, start_s[-1] + length_m[-1])
        xy[row, count + 1 :], s[row, count + 1 :] = xy[row, count], s[row, count]
    return _Nodes(xy, s, real)


@dataclass(frozen=True)
class _Road:
    """Trial roads ``(polylines, trials)``: the first node's sideways ``offset`` from the
    road's start (m, along the normal of ``base_heading``), the start heading's ``turn``
    from ``base_heading`` (rad), part ``bounds`` ``(..., parts + 1)`` in the road's arc
    length, part ``curvature`` and which parts are ``free`` to curve, and ``last``, the
    index of the last part of each (the parts after it are padding of no length). The
    first part extends backwards and the last forwards without end."""

    base_heading: np.ndarray
    offset: np.ndarray
    turn: np.ndarray
    bounds: np.ndarray
    curvature: np.ndarray
    free: np.ndarray
    last: np.ndarray

    def start(self) -> np.ndarray:
        """The road's start point (complex), the first node being at 0."""
        return 1j * np.exp(1j * self.base_heading) * self.offset

    def heading(self) -> np.ndarray:
        """The road's heading at its start, rad."""
        return self.base_heading + self.turn

    def parameters(self) -> np.ndarray:
        """The parameters the polish moves, ``(..., 2 * parts + 1)``: offset, turn, inner bounds, curvatures."""
        return np.concatenate(
            (self.offset[..., None], self.turn[..., None], self.bounds[..., 1:-1], self.curvature), axis=-1
        )

    def movable(self) -> np.ndarray:
        """Which parameters move: the offset and turn, the knots between real parts and the free curvatures."""
        parts = self.curvature.shape[-1]
        knots = np.arange(1, parts) <= self.last[..., None]
        return np.concatenate((np.ones(self.offset.shape + (2,), dtype=bool), knots, self.free), axis=-1)

    def with_parameters(self, parameters: np.ndarray) -> _Road:
        """The roads with the :meth:`parameters` ``parameters`` (a part not free stays straight)."""
        parts = self.curvature.shape[-1]
        bounds = self.bounds.copy()
        bounds[..., 1:-1] = parameters[..., 2 : parts + 1]
        return _Road(
            self.base_heading,
            parameters[..., 0],
            parameters[..., 1],
            bounds,
            parameters[..., parts + 1 :] * self.free,
            self.free,
            self.last,
        )

    def feasible_fraction(self, step: np.ndarray) -> np.ndarray:
        """The largest fraction (at most 1, with a margin) of the parameter ``step`` that
        leaves every real part at least :data:`MIN_POLISHED_PART_M` long."""
        parts = self.curvature.shape[-1]
        moved = np.concatenate(
            (np.zeros_like(step[..., :1]), step[..., 2 : parts + 1], np.zeros_like(step[..., :1])), axis=-1
        )
        shrink = -np.diff(moved, axis=-1)
        room = np.diff(self.bounds, axis=-1) - MIN_POLISHED_PART_M
        real = np.arange(parts) <= self.last[..., None]
        with np.errstate(divide="ignore", invalid="ignore"):
            limit = np.where(real & (shrink > 0), np.fmax(room, 0.0) / shrink, np.inf)
        return np.fmin(1.0, 0.9 * limit.min(axis=-1))

    def is_ordered(self) -> np.ndarray:
        """Whether every real part is at least :data:`MIN_POLISHED_PART_M` long."""
        real = np.arange(self.curvature.shape[-1]) <= self.last[..., None]
        return np.all((np.diff(self.bounds, axis=-1) >= MIN_POLISHED_PART_M) | ~real, axis=-1)


def _chord(length: np.ndarray, heading: np.ndarray, curvature: np.ndarray) -> np.ndarray:
    """The chord (complex) of a part of ``length`` that starts at ``heading`` and curves by
    ``curvature``: ``l·exp(i(φ + a/2))·sin(a/2)/(a/2)`` with ``a = κ l`` the angle it turns,
    exact on a straight (a = 0) and without cancellation near it."""
    half_turn = 0.5 * curvature * length
    return length * np.sinc(half_turn / np.pi) * np.exp(1j * (heading + half_turn))


def _area_factor(angle: np.ndarray) -> np.ndarray:
    """``(1 + i a - exp(i a)) / a²``: the integral of a part's points over its length l
    from its start A with heading φ is ``l A + l² exp(i φ)`` times this."""
    small = np.abs(angle) < 1e-2
    safe = np.where(small, 1.0, angle)
    series = 0.5 + angle * (1j / 6.0 - angle * (1.0 / 24.0 + angle * (1j / 120.0 - angle / 720.0)))
    return np.where(small, series, (1.0 + 1j * safe - np.exp(1j * safe)) / safe**2)


@dataclass(frozen=True)
class _RoadPoints:
    """The road at the nodes' positions ``t`` ``(polylines, trials, nodes)``: ``point``
    (complex), ``heading``, the ``part`` each is on and its ``progress`` along that part
    from the part's start; per part ``(..., parts)``, its start point ``corner``, start
    heading ``part_heading`` and ``length``."""

    point: np.ndarray
    heading: np.ndarray
    part: np.ndarray
    progress: np.ndarray
    corner: np.ndarray
    part_heading: np.ndarray
    length: np.ndarray


def _road_points(road: _Road, t: np.ndarray) -> _RoadPoints:
    """The road's points and headings at the arc lengths ``t``."""
    length = np.diff(road.bounds, axis=-1)
    turned = np.cumsum(road.curvature * length, axis=-1)
    part_heading = road.heading()[..., None] + np.concatenate(
        (np.zeros_like(turned[..., :1]), turned[..., :-1]), axis=-1
    )
    moved = np.cumsum(_chord(length, part_heading, road.curvature), axis=-1)
    corner = road.start()[..., None] + np.concatenate((np.zeros_like(moved[..., :1]), moved[..., :-1]), axis=-1)
    part = np.minimum((t[..., None] >= road.bounds[..., None, 1:-1]).sum(axis=-1), road.last[..., None])
    progress = t - np.take_along_axis(road.bounds, part, axis=-1)
    curvature = np.take_along_axis(road.curvature, part, axis=-1)
    heading = np.take_along_axis(part_heading, part, axis=-1)
    point = np.take_along_axis(corner, part, axis=-1) + _chord(progress, heading, curvature)
    return _RoadPoints(point, heading + curvature * progress, part, progress, corner, part_heading, length)


def _projected(road: _Road, nodes: _Nodes, t: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray, _RoadPoints]:
    """The nodes projected onto the road by ``steps`` Newton steps along it from ``t``;
    returns their arc lengths after one step more, their sideways distances (left
    positive) from the road's tangent where they are, and the road there."""
    xy = nodes.xy[:, None, :]
    for _ in range(steps):
        at = _road_points(road, t)
        t = t + np.real(np.exp(-1j * at.heading) * (xy - at.point))
    at = _road_points(road, t)
    offset = np.exp(-1j * at.heading) * (xy - at.point)
    return t + np.real(offset), np.imag(offset) * nodes.real[:, None, :], at


def _sideways_jacobian(road: _Road, at: _RoadPoints) -> np.ndarray:
    """Derivatives of the nodes' sideways distances by the road's parameters, ``(..., nodes, 2 * parts + 1)``.

    With the nodes' arc lengths held, a parameter moves each node's road point by dP and
    its distance by ``-Im(conj(T) dP)`` (T the unit tangent). Turning the start turns the
    road about its start; moving knot k turns the road after it about the knot's corner
    by the change of curvature there; a part's curvature moves a point by
    ``i ∫ (P - P(u)) du`` over the part up to it, an integral :func:`_area_factor` gives.
    """
    back = np.exp(-1j * at.heading)
    back_real, back_imag = back.real[..., None], back.imag[..., None]

    def along_tangent(per_part: np.ndarray) -> np.ndarray:
        """``Re(conj(T) z)`` of each part's ``z`` at every node, ``(..., nodes, parts)``."""
        return back_real * per_part.real[..., None, :] - back_imag * per_part.imag[..., None, :]

    point_along = np.real(back * at.point)
    offset = -np.imag(back * 1j * np.exp(1j * road.base_heading)[..., None])
    turn = -(point_along - np.real(back * road.start()[..., None]))
    parts = np.arange(road.curvature.shape[-1])
    step = (road.curvature[..., :-1] - road.curvature[..., 1:])[..., None, :]
    knots = -step * (point_along[..., None] - along_tangent(at.corner[..., 1:])) * (at.part[..., None] >= parts[1:])
    full_area = at.length * at.corner + at.length**2 * np.exp(1j * at.part_heading) * _area_factor(
        road.curvature * at.length
    )
    own_curvature = np.take_along_axis(road.curvature, at.part, axis=-1)
    own_corner = np.take_along_axis(at.corner, at.part, axis=-1)
    own_heading = np.take_along_axis(at.part_heading, at.part, axis=-1)
    own_area = at.progress * own_corner + at.progress**2 * np.exp(1j * own_heading) * _area_factor(
        own_curvature * at.progress
    )
    passed = at.part[..., None] > parts
    curvatures = np.where(passed, along_tangent(full_area) - at.length[..., None, :] * point_along[..., None], 0.0)
    np.put_along_axis(
        curvatures, at.part[..., None], (np.real(back * own_area) - at.progress * point_along)[..., None], axis=-1
    )
    return np.concatenate((offset[..., None], turn[..., None], knots, curvatures), axis=-1)


def _polished(
    road: _Road,
    nodes: _Nodes,
    iterations: int = POLISH_ITERATIONS,
    wanted: np.ndarray | None = None,
    scales: tuple[float, ...] = STEP_SCALES,
) -> tuple[_Road, np.ndarray]:
    """The trial roads moved by Levenberg-Marquardt steps to where the nodes' sideways
    distances are least; returns them and that sum of squares ``(polylines, trials)``.
    Only the ``wanted`` trials (all if not given) are moved; each step is also tried
    ``scales`` times as long (:func:`_best_scaled_step`).

    Each trial is its own problem; one stops when a step no longer gains or the damping
    has grown to :data:`MAX_DAMPING`, so that the iterations are spent on those still moving.
    """
    polylines, trials = road.offset.shape
    road = _Road(
        *(np.array(getattr(road, f.name).reshape((-1, 1) + getattr(road, f.name).shape[2:])) for f in fields(_Road))
    )
    nodes = _Nodes(*(np.repeat(getattr(nodes, f.name), trials, axis=0) for f in fields(_Nodes)))
    t, distance, at = _projected(road, nodes, nodes.s[:, None, :].copy(), PROJECTION_STEPS)
    squares = np.einsum("ptn,ptn->pt", distance, distance)
    damping = np.full(squares.shape, 1e-3)
    active = np.arange(len(squares)) if wanted is None else np.flatnonzero(wanted)
    for _ in range(iterations):
        if active.size == 0:
            break
        here, here_nodes = _road_rows(road, active), _nodes_rows(nodes, active)
        step, sound = _damped_step(here, here_nodes, _points_rows(at, active), distance[active], damping[active])
        trial = _best_scaled_step(here, here_nodes, t[active], step, scales)
        better = (trial.road.is_ordered() & (trial.squares < squares[active]))[:, 0]
        gain = squares[active, 0] - trial.squares[:, 0]
        moved = active[better]
        _put_rows(road, moved, trial.road, better)
        _put_rows(at, moved, trial.at, better)
        t[moved], distance[moved], squares[moved] = trial.t[better], trial.distance[better], trial.squares[better]
        damping[active] = np.where(better, np.fmax(damping[active, 0] / 10.0, MIN_DAMPING), damping[active, 0] * 10.0)[
            :, None
        ]
        done = (
            np.where(better, gain <= POLISH_TOLERANCE * squares[active, 0], damping[active, 0] >= MAX_DAMPING)
            | ~sound[:, 0]
        )
        active = active[~done]
    return _Road(
        *(getattr(road, f.name).reshape((polylines, trials) + getattr(road, f.name).shape[2:]) for f in fields(_Road))
    ), squares.reshape(polylines, trials)


def _damped_step(
    road: _Road, nodes: _Nodes, at: _RoadPoints, distance: np.ndarray, damping: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The Levenberg-Marquardt step of each trial road (one per row) towards the least sum of the
    nodes' squared sideways ``distance``, with its ``damping``; and whether the trial is sound (a
    trial gone non-finite, a degenerate road, takes no step and stops)."""
    jacobian = _sideways_jacobian(road, at) * (nodes.real[:, None, :, None] * road.movable()[..., None, :])
    normal = np.swapaxes(jacobian, -1, -2) @ jacobian
    gradient = np.einsum("ptnm,ptn->ptm", jacobian, distance)
    sound = np.isfinite(normal).all(axis=(-2, -1)) & np.isfinite(gradient).all(axis=-1)
    normal, gradient = np.where(sound[..., None, None], normal, 0.0), np.where(sound[..., None], gradient, 0.0)
    diagonal = np.einsum("...mm->...m", normal)
    flat = diagonal <= 1e-12 * diagonal.max(axis=-1, keepdims=True)
    normal += np.eye(normal.shape[-1]) * (damping[..., None] * diagonal + flat)[..., None, :]
    return _solved(normal, -gradient), sound


@dataclass(frozen=True)
class _Moved:
    """Roads ``(polylines, 1)`` after a polish step: the ``road``, the nodes' arc lengths
    ``t`` on it, their sideways ``distance``, the road ``at`` them and their sum of ``squares``."""

    road: _Road
    t: np.ndarray
    distance: np.ndarray
    at: _RoadPoints
    squares: np.ndarray


def _put_rows(target: Any, rows: np.ndarray | tuple, source: Any, take: np.ndarray | tuple) -> None:
    """Every array of the dataclass ``target`` (and of those in it) at ``rows`` set to ``source``'s at ``take``."""
    for field in fields(target):
        value = getattr(target, field.name)
        if is_dataclass(value):
            _put_rows(value, rows, getattr(source, field.name), take)
        else:
            value[rows] = getattr(source, field.name)[take]


def _moved(road: _Road, nodes: _Nodes, t: np.ndarray, step: np.ndarray) -> _Moved:
    """The roads ``road`` moved by the parameter ``step`` (as much of it as is feasible)."""
    trial = road.with_parameters(road.parameters() + step * road.feasible_fraction(step)[..., None])
    trial_t, distance, at = _projected(trial, nodes, t, 0)
    return _Moved(trial, trial_t, distance, at, np.einsum("ptn,ptn->pt", distance, distance))


def _best_scaled_step(road: _Road, nodes: _Nodes, t: np.ndarray, step: np.ndarray, scales: tuple[float, ...]) -> _Moved:
    """The roads ``road`` ``(polylines, 1)`` moved by the parameter ``step`` or by the
    multiple of it in ``scales`` (:data:`STEP_SCALES` in a full polish) that leaves the
    nodes closer.

    With the nodes held at their arc lengths, the linear model of the distances bends
    more than they do when the nodes slide along the road: along a gentle curve's start
    and end together, Gauss-Newton steps each go a small part of the way, in the same
    direction. A longer step in that direction goes further at the cost of a projection.
    """
    every = np.array((1.0, *scales))
    roads = _repeated(road, len(every))
    moved = _moved(roads, nodes, t, step * every[:, None])
    return _chosen(moved, np.argmin(np.where(moved.road.is_ordered(), moved.squares, np.inf), axis=1)[:, None])


def _solved(normal: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Solutions of the damped normal equations ``normal @ x = right``; where one is
    singular in floating point (parameters the nodes cannot tell apart), the least-norm one."""
    try:
        return np.linalg.solve(normal, right[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return (np.linalg.pinv(normal, hermitian=True) @ right[..., None])[..., 0]


def _points_rows(at: _RoadPoints, rows: np.ndarray) -> _RoadPoints:
    """The road points of the trials ``rows``."""
    return _RoadPoints(*(getattr(at, f.name)[rows] for f in fields(_RoadPoints)))


def _base_road(
    batch: _SparseBatch, bounds: np.ndarray, curvature: np.ndarray, free: np.ndarray, knots: np.ndarray
) -> _Road:
    """The road of the heading fit, one trial per polyline: its start heading is the
    weighted mean of the chords' headings less the turn the fit predicts over each."""
    turn = np.einsum(
        "pnk,pk->pn", _chord_means_of_ramps(batch, bounds[:, None, :-1], np.diff(bounds)[:, None, :])[:, 0], curvature
    )
    weight = batch.root_weight**2
    base_heading = np.sum(weight * (batch.heading - turn), axis=1) / np.sum(weight, axis=1)
    zero = np.zeros((len(bounds), 1))
    return _Road(
        base_heading[:, None],
        zero,
        zero.copy(),
        bounds[:, None, :],
        curvature[:, None, :],
        free[:, None, :],
        knots[:, None],
    )


def _repeated(road: _Road, count: int) -> _Road:
    """The trial roads ``(polylines, 1)`` each repeated ``count`` times, ``(polylines, count)``."""
    return _Road(*(np.repeat(getattr(road, f.name), count, axis=1) for f in fields(_Road)))


def _road_rows(road: _Road, rows: np.ndarray) -> _Road:
    """The trial roads of the polylines ``rows``."""
    return _Road(*(getattr(road, f.name)[rows] for f in fields(_Road)))


def _split_part(road: _Road, part: np.ndarray, knot: np.ndarray, before: np.ndarray, after: np.ndarray) -> _Road:
    """The trial roads with their part ``part`` split at ``knot`` into two parts of
    curvature ``before`` and ``after`` (a curvature of 0 makes a straight), all ``(polylines, trials)``."""
    parts = road.curvature.shape[-1]
    index = np.arange(parts + 1)
    split = part[..., None]
    old = np.minimum(index - (index > split), parts - 1)
    curvature = np.take_along_axis(road.curvature, old, axis=-1)
    free = np.take_along_axis(road.free, old, axis=-1)
    curvature = np.where(index == split, before[..., None], np.where(index == split + 1, after[..., None], curvature))
    free = np.where(index == split, before[..., None] != 0, np.where(index == split + 1, after[..., None] != 0, free))
    bounds = np.sort(np.concatenate((road.bounds, knot[..., None]), axis=-1), axis=-1)
    return _Road(road.base_heading, road.offset, road.turn, bounds, curvature * free, free, road.last + 1)


def _chosen(trials: Any, trial: np.ndarray) -> Any:
    """The dataclass of ``(polylines, trials, ...)`` arrays ``trials`` (and those in it) at
    the trials ``trial`` ``(polylines, k)`` of each polyline."""
    rows = np.arange(len(trial))[:, None]

    def chosen(values: Any) -> Any:
        return _chosen(values, trial) if is_dataclass(values) else values[rows, trial]

    return type(trials)(*(chosen(getattr(trials, f.name)) for f in fields(trials)))


def _nodes_rows(nodes: _Nodes, rows: np.ndarray, most: int | None = None) -> _Nodes:
    """The nodes of the polylines ``rows`` (the first ``most`` of each, if given)."""
    return _Nodes(nodes.xy[rows, :most], nodes.s[rows, :most], nodes.real[rows, :most])
