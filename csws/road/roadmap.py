"""Holds every lane of a SUMO network with its shape, links and curves: the road map.

A :class:`RoadMap` is read once from a ``.net.xml`` (or ``.net.xml.gz``) and then
answers the questions the warning needs about the road ahead:

* which lanes a vehicle at (x, y) may be on, where along them and heading which way
  (:meth:`RoadMap.nearest_lanes`, :meth:`RoadMap.match_points` for many fixes at once;
  the lanes themselves, their shapes and links, are the lane map it extends,
  :class:`csws.road.lanemap.LaneMap`);
* where the curves are: per lane (:meth:`RoadMap.lane_curves`, :meth:`RoadMap.curves`)
  and along a path of consecutive lanes (:meth:`RoadMap.path_profile`). A path is
  stitched into one polyline before it is profiled, so a curve that crosses an edge
  boundary or a junction is one curve with one start (3.4) and one end (3.5), and the
  look-ahead distance (3.9) to it and to its CPOI (3.11) is measured along the path.

Every lane of the network is kept, internal junction lanes included, because a vehicle
drives through them and they carry the turns: a path runs normal lane -> internal
"via" lane(s) -> next normal lane, exactly as SUMO moves vehicles. Pedestrian crossings
and walking areas are left out.

Junction manoeuvres are not curves of the road. A turn from one road into another (an
internal lane whose connection leaves the road chain, :mod:`csws.road.continuations`) or a drive
round a roundabout (the edges of the network's ``<roundabout>`` elements) is taken at
junction speed, not a bend taken at road speed. A curve of the road with a node inside
it (a way split, a side road joining) is a curve whole: each road chain (the lanes a
road continues on, through the internal lanes that continue it, taken as one chord
across the junction) is fitted once, and the curve index and every path read that fit
(:mod:`csws.road.chains`). The lanes of one road share its curves: a lane beside its edge's
reference lane borrows that lane's fit, at the same lane positions, its radii moved by the
lanes' lateral offset (:mod:`csws.road.sharing`).

Networks imported from OpenStreetMap are geo-referenced: :meth:`RoadMap.xy_to_lonlat`
and :meth:`RoadMap.lonlat_to_xy` (and their vectorised ``*_many`` variants) convert with
the network's own projection (UTM for an OSM import); :mod:`csws.road.export` gives the curve
index as a table, JSON, CSV or GeoJSON.

Storage is columnar (:mod:`csws.road.lanemap`), and all road chains are profiled in one
:func:`csws.curvature.radius_profiles` call, so a regional network of some 1,500 lane-km
loads and profiles in seconds.

Lane positions follow SUMO (``length / shape length``, :mod:`csws.road.lanemap`); radius
profiles and the :class:`~csws.curvature.Curve` objects they yield are in shape arc length.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import sumolib

from csws.curvature import checked_warning_radius_m, profile_cache_dir
from csws.road.chains import LaneCurve, RoadChains, fit_road_chains, index_curves, road_curve_id
from csws.road.lanemap import LaneMap
from csws.road.netcache import read_net_lanes
from csws.road.network import Lane, NetLanes, NetworkError, net_lanes, read_sumo_net
from csws.road.path import PathProfile, path_profile
from csws.road.search import LaneMatch, LaneMatches
from csws.standard import DEFAULT_POLICY, DEFAULT_WARNING_RADIUS_M, WarningSpeedPolicy

if TYPE_CHECKING:
    from csws.opendrive.exact import ExactLane

__all__ = [
    "Lane",
    "LaneCurve",
    "LaneMatch",
    "LaneMatches",
    "NetworkError",
    "PathProfile",
    "RoadMap",
    "read_sumo_net",
]


def _shape_between(shape: np.ndarray, start_s: float, end_s: float) -> np.ndarray:
    """The part of a polyline between two arc lengths, its ends interpolated, ``(m, 2)``."""
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T))))
    inside = (s > start_s) & (s < end_s)
    cut_s = np.concatenate(([start_s], s[inside], [end_s]))
    return np.column_stack((np.interp(cut_s, s, shape[:, 0]), np.interp(cut_s, s, shape[:, 1])))


class RoadMap(LaneMap):
    """Every lane of a SUMO network (a :class:`~csws.road.lanemap.LaneMap`) with its road's radius profile and curves.

    Build one with :meth:`load` (from a file) or :meth:`from_net` (from a sumolib net).
    Lanes are addressed by their SUMO id.

    Attributes
    ----------
    warning_radius_m
        Warning curvature radius R_c (3.2) the per-lane curves were found with, m.
    """

    def __init__(
        self,
        lanes: Sequence[Lane],
        xy: np.ndarray,
        vertex_start: np.ndarray,
        successors: Sequence[Sequence[int]],
        geo: sumolib.net.Net,
        warning_radius_m: float = DEFAULT_WARNING_RADIUS_M,
        *,
        cache: bool = True,
        warning_policy: WarningSpeedPolicy = DEFAULT_POLICY,
        exact_lanes: Mapping[str, ExactLane] | None = None,
    ) -> None:
        """Profile the lanes and find their curves.

        Parameters
        ----------
        lanes, xy, vertex_start, successors, geo
            The lanes, their shapes and links, as :class:`~csws.road.lanemap.LaneMap` holds them.
        warning_radius_m
            Warning curvature radius R_c (3.2), m.
        cache
            Whether to read the road chains' fit from the profile cache, and write it there
            when it is not yet (:func:`csws.curvature.profile_cache_dir`).
        warning_policy
            The warning speeds the curves' clothoids are cut into CPOIs by (a piece's V_w changes
            by under :data:`csws.curvature.curves.SPIRAL_PIECE_KMH`): those the warning uses.
        exact_lanes
            The exact curvature of lanes of a network imported from OpenDRIVE, by lane id: the
            road chains of those lanes read it and are not fitted (:mod:`csws.opendrive.profiles`).
        """
        self.warning_radius_m = checked_warning_radius_m(warning_radius_m)
        self.warning_policy = warning_policy
        super().__init__(lanes, xy, vertex_start, successors, geo)
        self.exact_lanes = dict(exact_lanes or {})
        given = None
        if self.exact_lanes:
            from csws.opendrive.profiles import given_exact_profiles

            given = given_exact_profiles(self.lane_ids, self.exact_lanes)
        self._chains = fit_road_chains(
            np.array([self._index.get(lane.continues_into, -1) for lane in self._lanes], dtype=np.int64),
            self._road_shapes,
            self._lane_length_m,
            self._lane_is_junction,
            profile_cache_dir() if cache else None,
            edge_ids=[lane.edge_id for lane in self._lanes],
            lane_index=[lane.index for lane in self._lanes],
            given=given,
        )
        self._edge_ids = tuple(lane.edge_id for lane in self._lanes)
        self._curve_index = index_curves(
            self._chains, self.lane_ids, self._edge_ids, self.warning_radius_m, warning_policy
        )

    # ----------------------------------------------------------------- construction
    @classmethod
    def load(
        cls,
        net_path: str | Path,
        warning_radius_m: float | None = None,
        *,
        cache: bool = True,
        warning_policy: WarningSpeedPolicy = DEFAULT_POLICY,
    ) -> RoadMap:
        """Read a ``.net.xml`` / ``.net.xml.gz`` and build its road map.

        Parameters
        ----------
        net_path
            The SUMO network.
        warning_radius_m
            Warning curvature radius R_c (3.2), m; ``None`` for the default
            :data:`csws.standard.DEFAULT_WARNING_RADIUS_M`.
        cache
            Whether to use the profile cache (see :class:`RoadMap`): a network fitted once
            loads in a fraction of the time.
        warning_policy
            The warning speeds the curves' clothoids are cut by (see :class:`RoadMap`).

        A network imported from OpenDRIVE (``csws import-opendrive``) has its lanes' exact
        curvature beside it (``NAME.kappa.json``): the road map reads that instead of the fit.

        Raises
        ------
        NetworkError
            If the file is missing, not a SUMO network, or has no lanes.
        """
        from csws.opendrive.profiles import exact_lanes_beside

        lanes = read_net_lanes(net_path, profile_cache_dir() if cache else None)
        exact = exact_lanes_beside(net_path)
        return cls.of_lanes(lanes, warning_radius_m, cache=cache, warning_policy=warning_policy, exact_lanes=exact)

    @classmethod
    def from_net(
        cls,
        net: sumolib.net.Net,
        warning_radius_m: float | None = None,
        *,
        cache: bool = True,
        warning_policy: WarningSpeedPolicy = DEFAULT_POLICY,
        exact_lanes: Mapping[str, ExactLane] | None = None,
    ) -> RoadMap:
        """Build the road map of a sumolib net read with ``withInternal=True``.

        Only the location of ``net`` is kept: lanes are copied into arrays so the
        sumolib objects can be freed.
        """
        return cls.of_lanes(
            net_lanes(net), warning_radius_m, cache=cache, warning_policy=warning_policy, exact_lanes=exact_lanes
        )

    @classmethod
    def of_lanes(
        cls,
        lanes: NetLanes,
        warning_radius_m: float | None = None,
        *,
        cache: bool = True,
        warning_policy: WarningSpeedPolicy = DEFAULT_POLICY,
        exact_lanes: Mapping[str, ExactLane] | None = None,
    ) -> RoadMap:
        """Build the road map of what it keeps of a SUMO network (:func:`csws.road.network.net_lanes`)."""
        radius = DEFAULT_WARNING_RADIUS_M if warning_radius_m is None else warning_radius_m
        return cls(
            lanes.lanes,
            lanes.xy,
            lanes.vertex_start,
            lanes.successors,
            lanes.geo,
            radius,
            cache=cache,
            warning_policy=warning_policy,
            exact_lanes=exact_lanes,
        )

    # ----------------------------------------------------------------- curves
    @property
    def nbytes(self) -> int:
        """Bytes held by the map's arrays: vertices, arc lengths, links, road chains and their profiles."""
        arrays = [self._xy, self._vertex_s, self._vertex_start, self._successor_start, self._successor_index]
        profiles = {id(p): p for p in (*self._chains.profiles, *self._chains.fitted) if p is not None}.values()
        arrays += list(self._chains.xy) + [a for p in profiles for a in (p.s, p.curvature, p.radius)]
        return int(sum(array.nbytes for array in arrays))

    @property
    def chains(self) -> RoadChains:
        """The road chains: each road's lanes stitched into one polyline, with its fit (:mod:`csws.road.chains`)."""
        return self._chains

    def road_chain(self, lane_id: str) -> tuple[str, ...]:
        """The lanes of the road chain ``lane_id`` belongs to, in driving order (:mod:`csws.road.chains`)."""
        chain = self._chains.lane_chain[self._lane_index(lane_id)]
        return tuple(self._lanes[i].lane_id for i in self._chains.lanes[chain].tolist())

    def lane_curves(self, lane_id: str) -> tuple[LaneCurve, ...]:
        """The curves of the road (radius <= :attr:`warning_radius_m`) that lie on ``lane_id``, whole
        or in part, in driving order."""
        lane = self._lane_index(lane_id)
        start_s = self._chains.lane_start_s[lane]
        end_s = start_s + self._chains.lane_road_length_m[lane]
        return tuple(
            lane_curve
            for lane_curve in self._curve_index[self._chains.lane_chain[lane]]
            if lane_curve.curve.end_s > start_s and lane_curve.curve.start_s < end_s
        )

    def curves(self, include_junctions: bool = False) -> list[LaneCurve]:
        """The curves of every road, road chain by road chain: the curve index.

        Each curve is listed once, at the lane where it starts, even where it runs on
        through a node into further lanes of its road; the warning reads the same curves
        (:meth:`path_profile`).

        Parameters
        ----------
        include_junctions
            Also list the curves of junction manoeuvres (turns from one road into
            another on internal lanes, roundabouts), left out by default.
        """
        return [
            lane_curve
            for chain_index, lane_curves in enumerate(self._curve_index)
            if include_junctions or not self._chains.is_junction[chain_index]
            for lane_curve in lane_curves
        ]

    def curve_slopes(self, lane_curve: LaneCurve) -> dict[str, float] | None:
        """Mean grade and superelevation along a curve, per cent, on a network imported from OpenDRIVE
        (:func:`csws.opendrive.profiles.curve_slopes`); None elsewhere."""
        if not self.exact_lanes:
            return None
        from csws.opendrive.profiles import curve_slopes

        lengths = {lane_id: self.lane(lane_id).length_m for lane_id in (lane_curve.lane_id, lane_curve.end_lane_id)}
        return curve_slopes(self.exact_lanes, lengths, lane_curve)

    def road_position(self, chain: int, s: float) -> tuple[str, float]:
        """The lane id and lane position of arc length ``s`` along road chain ``chain``
        (a :attr:`LaneCurve.chain`, or a chain from :meth:`PathProfile.curve_sources`)."""
        lane, lane_pos_m = self._chains.lane_position(chain, s)
        return self._lanes[lane].lane_id, lane_pos_m

    def curve_id(self, chain: int, start_s: float, warning_radius_m: float) -> tuple[str, int]:
        """The id of the road's curve starting at arc length ``start_s`` of road chain ``chain`` (found with R_c
        ``warning_radius_m``), the same on every lane of the road, and the index of its first part there
        (:func:`csws.road.chains.road_curve_id`)."""
        return road_curve_id(self._chains, self._edge_ids, chain, start_s, warning_radius_m, self.warning_policy)

    def curve_shape(self, lane_curve: LaneCurve) -> np.ndarray:
        """The road's polyline from a curve's start (3.4) to its end (3.5), ``(m, 2)``, m."""
        return _shape_between(self._chains.xy[lane_curve.chain], lane_curve.curve.start_s, lane_curve.curve.end_s)

    # ----------------------------------------------------------------- paths
    def path_profile(self, lane_ids: Sequence[str]) -> PathProfile:
        """The road along consecutive lanes: one polyline, with the profile and curves of its road chains.

        A curve that runs across an edge boundary or through a node of its road is one
        curve (3.4-3.5), the same curve the index lists, wherever the path starts. Where
        the path leaves a road (a turn at a junction) it runs on along the next road's
        chain. Internal via lanes missing from ``lane_ids`` are filled in (:meth:`expand_path`).
        """
        indices = self._expanded_indices(lane_ids)
        lane_ids_by_index, road_shapes = self.lane_ids, self._road_shapes
        return path_profile(
            self._chains,
            indices,
            [lane_ids_by_index[i] for i in indices],
            [road_shapes[i] for i in indices],
            self._lane_length_m[indices],
            self._lane_is_junction[indices],
            self.warning_policy,
        )

    # ----------------------------------------------------------------- internals
    @cached_property
    def _road_shapes(self) -> tuple[np.ndarray, ...]:
        """The shape a path takes along each lane (:meth:`_road_shape`), by index: the road chains are fitted
        to them, and every path built reads them."""
        return tuple(self._road_shape(lane) for lane in range(len(self._lanes)))

    @cached_property
    def _lane_length_m(self) -> np.ndarray:
        """The SUMO length of each lane, by index, m."""
        return np.array([lane.length_m for lane in self._lanes])

    @cached_property
    def _lane_is_junction(self) -> np.ndarray:
        """Whether each lane is a junction manoeuvre, by index."""
        return np.array([lane.is_junction for lane in self._lanes], dtype=bool)

    def _road_shape(self, lane: int) -> np.ndarray:
        """The shape a path takes along a lane: the lane's own, but only the two ends of an
        internal lane that continues the road (:attr:`Lane.continues_road`).

        netconvert trims the edges back to the junction border and joins them with a shape
        of its own making, which bends sharply where a side road widens the junction; the
        mapped road is the edges either side. One chord across the junction keeps its
        heading (on a circle a chord is parallel to the tangent at its middle) without the
        made-up bends, so a curve through the junction is fitted from the road's own shape.
        """
        shape = self._shape(lane)
        return shape[[0, -1]] if self._lanes[lane].continues_road and len(shape) > 2 else shape
