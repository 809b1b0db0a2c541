"""From validated queries to answers: map matching, the engines, and the answers' JSON form.

:class:`WarningService` is what the HTTP endpoints call. For a batch it

1. reads the vehicles of the batch from the state store (:mod:`service.vehicles`);
2. checks what the models cannot (lane and edge ids, lane positions, lon/lat on
   networks without a projection, a missing category) and reports every problem with
   the index of its query (:class:`QueryErrors`, an HTTP 422);
3. matches every fix without a lane id (:class:`csws.road.matching.MapMatcher`, one spatial index
   over all served networks): a query naming its network on that network alone, a vehicle
   with a session on its previous network first, preferring its previous lane;
4. evaluates the vehicles of each network in one :meth:`csws.engine.Engine.evaluate_fleet`;
5. writes the vehicles' sessions back to the store, and the answers as the JSON of the HTTP
   contract (floats unrounded), encoded by msgspec.

A vehicle queried twice in one batch is evaluated in order: the batch is cut into
rounds holding each vehicle at most once.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any, NamedTuple

import msgspec
import numpy as np

from csws.ahead.horizon import PathAhead
from csws.engine import VehicleInput
from csws.road.matching import MapMatcher, MatchSettings, Probes, lane_points
from csws.standard import Category, Level
from csws.state import Fault, SystemState
from csws.warning.rules import CurveWarning, HmiHint, PathKind, Trigger

from .decoding import DecodedQuery
from .fcw import fcw_answers
from .horizon import CpoiPositions
from .keys import shown_id, vehicle_key
from .networks import ServedNetwork
from .schemas import Hmi, Matched, WarningAnswer
from .timing import UNTIMED, Stages
from .vehicles import LatestAnswer, LoadedVehicles, VehicleRegistry

__all__ = ["QueryErrors", "Placement", "Evaluated", "EncodedAnswers", "WarningService"]


class QueryErrors(ValueError):
    """Queries the service cannot answer, with where and why (an HTTP 422).

    Attributes
    ----------
    errors
        ``{"loc": [...], "msg": ..., "type": ...}`` per problem, like pydantic's.
    """

    def __init__(self, errors: list[dict[str, Any]]) -> None:
        super().__init__("; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in errors))
        self.errors = errors


class Placement(NamedTuple):
    """Where one query was placed on the served networks.

    Attributes
    ----------
    network_index
        The network whose engine answers it.
    lane_id, lane_pos_m, distance_m
        The lane (None when nothing matched), the lane position and the distance of the fix from it, m.
    reason
        Why nothing matched, else None.
    """

    network_index: int
    lane_id: str | None
    lane_pos_m: float
    distance_m: float
    reason: str | None


def _error(loc: Sequence[Any], msg: str) -> dict[str, Any]:
    return {"loc": list(loc), "msg": msg, "type": "value_error"}


def _rounds(queries: Sequence[DecodedQuery], indices: Sequence[int]) -> list[list[int]]:
    """The indices of queries cut into rounds in which each vehicle appears once, in order."""
    seen: dict[str, int] = defaultdict(int)
    rounds: list[list[int]] = []
    for index in indices:
        vehicle_id = queries[index].vehicle_id
        occurrence = seen[vehicle_id]
        seen[vehicle_id] += 1
        if occurrence == len(rounds):
            rounds.append([])
        rounds[occurrence].append(index)
    return rounds


class WarningService:
    """Answers queries on the served networks.

    Parameters
    ----------
    networks
        The served networks.
    registry
        The vehicles' sessions and settings over the networks' engines.
    match_settings
        Map matching tolerances.
    """

    def __init__(
        self, networks: Sequence[ServedNetwork], registry: VehicleRegistry, match_settings: MatchSettings
    ) -> None:
        self.networks = list(networks)
        self.registry = registry
        self.matcher = MapMatcher([n.road_map for n in self.networks], match_settings)
        self.geo_networks = [i for i, n in enumerate(self.networks) if n.road_map.has_projection]
        self.edge_ids = frozenset().union(*(n.edge_ids for n in self.networks))
        self.network_index = {n.name: i for i, n in enumerate(self.networks)}
        self.cpoi_positions = [CpoiPositions(network) for network in self.networks]

    # ------------------------------------------------------------------ queries
    def answer(
        self,
        queries: Sequence[DecodedQuery],
        loc: Sequence[Any] = ("body", "queries"),
        fleet: str = "",
        stages: Stages = UNTIMED,
    ) -> EncodedAnswers:
        """The answers of ``queries`` of ``fleet``'s vehicles (:func:`service.keys.vehicle_key`), in order, as JSON.

        The vehicles are read from the state store, answered, and their sessions written back
        (:meth:`service.vehicles.VehicleRegistry.transact`); the time of each stage is counted in
        ``stages``.

        Raises
        ------
        QueryErrors
            If any query names an unknown lane or edge, lies beyond its lane, sends
            lon/lat to networks without a projection, or has no category; nothing is
            evaluated then.
        StoreUnavailable
            When the state store cannot be read or written now.
        """
        if fleet:
            queries = [
                msgspec.structs.replace(query, vehicle_id=vehicle_key(fleet, query.vehicle_id)) for query in queries
            ]
        answers = EncodedAnswers([None] * len(queries), [SystemState.OFF] * len(queries), [Level.NONE] * len(queries))

        def answer_vehicles(vehicles: LoadedVehicles, vehicle_ids: Collection[str]) -> None:
            with stages("check"):
                indices = [i for i, query in enumerate(queries) if query.vehicle_id in vehicle_ids]
                self.check(queries, vehicles, loc, fleet, indices)
            for round_indices in _rounds(queries, indices):
                self._answer_round([queries[i] for i in round_indices], round_indices, vehicles, answers, fleet, stages)

        self.registry.transact({query.vehicle_id for query in queries}, answer_vehicles, stages)
        return answers

    def check(
        self,
        queries: Sequence[DecodedQuery],
        vehicles: LoadedVehicles,
        loc: Sequence[Any] = ("body", "queries"),
        fleet: str = "",
        indices: Sequence[int] | None = None,
    ) -> None:
        """Raise :class:`QueryErrors` listing what in ``queries`` (of ``fleet``'s vehicles, those at
        ``indices`` if given) the networks cannot answer."""
        errors: list[dict[str, Any]] = []
        for index in range(len(queries)) if indices is None else indices:
            problems = self._problems(queries[index], vehicles, fleet)
            if problems:
                where = [*loc, index] if loc and loc[-1] == "queries" else list(loc)
                errors += [_error([*where, field], message) for field, message in problems]
        if errors:
            raise QueryErrors(errors)

    def _problems(self, query: DecodedQuery, vehicles: LoadedVehicles, fleet: str) -> list[tuple[str, str]]:
        """What the networks cannot answer in one query: (field, why) each."""
        problems = []
        if query.category is None and vehicles.category(query.vehicle_id) is None:
            problems.append(
                (
                    "category",
                    "category is required: give it in the query or "
                    f"set it with PUT /v1/vehicles/{shown_id(fleet, query.vehicle_id)}",
                )
            )
        if query.network is not None and query.network not in self.network_index:
            return problems + [
                ("network", f"unknown network {query.network!r}: served are " + ", ".join(sorted(self.network_index)))
            ]
        if query.position is not None and query.position.is_geographic and not self._geographic(query):
            problems.append(
                (
                    "position",
                    "the served networks are not geo-referenced: give the position as x and y in network metres",
                )
            )
        if query.lane_id is not None:
            problems += self._lane_problems(query, vehicles)
        if query.route:
            known = (
                self.edge_ids if query.network is None else self.networks[self.network_index[query.network]].edge_ids
            )
            unknown = [edge for edge in query.route if edge not in known]
            if unknown:
                where_not = "in no served network" if query.network is None else f"not in network {query.network!r}"
                problems.append(("route", f"unknown edge id {unknown[0]!r}: {where_not}"))
        return problems

    def _geographic(self, query: DecodedQuery) -> bool:
        """Whether the query's network (or, without one, any served network) is geo-referenced."""
        if query.network is None:
            return bool(self.geo_networks)
        return self.network_index[query.network] in self.geo_networks

    def _lane_problems(self, query: DecodedQuery, vehicles: LoadedVehicles) -> list[tuple[str, str]]:
        network_index = self._lane_network(query, vehicles)
        if network_index is None:
            where_not = "in no served network" if query.network is None else f"not in network {query.network!r}"
            return [("lane_id", f"unknown lane id {query.lane_id!r}: {where_not}")]
        length_m = self.networks[network_index].road_map.lane(query.lane_id).length_m
        if query.lane_pos_m > length_m:
            return [
                (
                    "lane_pos_m",
                    f"lane position {query.lane_pos_m:g} m lies beyond the end of lane "
                    f"{query.lane_id!r} ({length_m:g} m long)",
                )
            ]
        return []

    def _lane_network(self, query: DecodedQuery, vehicles: LoadedVehicles) -> int | None:
        """The network a query's lane id is taken on: the one it names, else the vehicle's own if it has the
        lane, else the first that has it; None if none has it."""
        if query.network is not None:
            named = self.network_index[query.network]
            return named if self.networks[named].road_map.has_lane(query.lane_id) else None
        own = vehicles.network_of(query.vehicle_id)
        if self.networks[own].road_map.has_lane(query.lane_id):
            return own
        return next((i for i, network in enumerate(self.networks) if network.road_map.has_lane(query.lane_id)), None)

    # ------------------------------------------------------------------ evaluation
    def place(self, queries: Sequence[DecodedQuery], vehicles: LoadedVehicles) -> list[Placement]:
        """Where each query is: its given lane, or the map match of its fix (queries of distinct
        vehicles, preferring each one's previous lane)."""
        placements: list[Placement | None] = [None] * len(queries)
        on_lanes, to_match = [], []
        for i, query in enumerate(queries):
            (to_match if query.lane_id is None else on_lanes).append(i)
        if on_lanes:
            networks = [self._lane_network(queries[i], vehicles) for i in on_lanes]
            distances_m = self._fix_distances_m([queries[i] for i in on_lanes], networks)
            for i, network_index, distance_m in zip(on_lanes, networks, distances_m, strict=False):
                placements[i] = Placement(network_index, queries[i].lane_id, queries[i].lane_pos_m, distance_m, None)
        if to_match:
            fixes = [queries[i] for i in to_match]
            matched = self.matcher.match(
                self._probes(fixes),
                np.array([math.nan if query.heading_deg is None else query.heading_deg for query in fixes]),
                [vehicles.previous(query.vehicle_id) for query in fixes],
            )
            for i, query, network_index, lane_id, lane_pos_m, distance_m, reason in zip(
                to_match,
                fixes,
                matched.map_index.tolist(),
                matched.lane_id,
                matched.lane_pos_m.tolist(),
                matched.distance_m.tolist(),
                matched.reason,
                strict=False,
            ):
                if network_index < 0:
                    network_index = vehicles.network_of(query.vehicle_id)
                placements[i] = Placement(network_index, lane_id, lane_pos_m, distance_m, reason)
        return placements

    def _probes(self, queries: Sequence[DecodedQuery]) -> Probes:
        """Where to look for each query's fix: x, y on the network it names, else on every one;
        lon, lat in the projection of the network it names, else of each geo-referenced one."""
        rows, xy, map_index = [], [], []
        geographic: dict[int, list[int]] = defaultdict(list)
        for row, query in enumerate(queries):
            named = -1 if query.network is None else self.network_index[query.network]
            position = query.position
            if position.lon is None:
                rows.append(row)
                xy.append((position.x, position.y))
                map_index.append(named)
            else:
                for network_index in self.geo_networks if named < 0 else (named,):
                    geographic[network_index].append(row)
        for network_index, placed in geographic.items():
            lonlat = np.array([(queries[row].position.lon, queries[row].position.lat) for row in placed])
            rows += placed
            xy += self.networks[network_index].road_map.lonlat_to_xy_many(lonlat).tolist()
            map_index += [network_index] * len(placed)
        return Probes(
            len(queries),
            np.array(rows, dtype=np.intp),
            np.array(xy, dtype=float).reshape(-1, 2),
            np.array(map_index, dtype=np.intp),
        )

    def _fix_distances_m(self, queries: Sequence[DecodedQuery], networks: Sequence[int]) -> list[float]:
        """Distance from each query's fix to its given lane position on its network, m; 0 without a fix,
        or with lon/lat on a network without a projection. The queries on one lane are placed on it
        in one interpolation."""
        distances_m = [0.0] * len(queries)
        on_lane: dict[tuple[int, str], list[int]] = defaultdict(list)
        for row, (query, network_index) in enumerate(zip(queries, networks, strict=False)):
            position = query.position
            if position is not None and (position.lon is None or self.networks[network_index].road_map.has_projection):
                on_lane[(network_index, query.lane_id)].append(row)
        for (network_index, lane_id), rows in on_lane.items():
            road_map = self.networks[network_index].road_map
            fixes = [queries[row].position for row in rows]
            geographic = [k for k, fix in enumerate(fixes) if fix.lon is not None]
            xy = np.array([(fix.x, fix.y) if fix.lon is None else (0.0, 0.0) for fix in fixes])
            if geographic:
                lonlat = np.array([(fixes[k].lon, fixes[k].lat) for k in geographic])
                xy[geographic] = road_map.lonlat_to_xy_many(lonlat)
            lane_xy = lane_points(road_map, lane_id, np.array([queries[row].lane_pos_m for row in rows]))
            for row, (x, y), (lane_x, lane_y) in zip(rows, xy.tolist(), lane_xy.tolist(), strict=False):
                distances_m[row] = math.hypot(x - lane_x, y - lane_y)
        return distances_m

    def _answer_round(
        self,
        queries: Sequence[DecodedQuery],
        indices: Sequence[int],
        vehicles: LoadedVehicles,
        answers: EncodedAnswers,
        fleet: str,
        stages: Stages,
    ) -> None:
        """Answer queries of distinct vehicles of ``fleet`` into ``answers[indices]``."""
        with stages("match"):
            placements = self.place(queries, vehicles)
        by_network: dict[int, list[int]] = defaultdict(list)
        for row, (query, placement) in enumerate(zip(queries, placements, strict=False)):
            vehicles.place(query.vehicle_id, placement.network_index)
            by_network[placement.network_index].append(row)
        # The query's category, else the one its fleet set (the checks made sure one of them is there).
        categories = [
            query.category if query.category is not None else vehicles.category(query.vehicle_id) for query in queries
        ]
        for network_index, rows in by_network.items():
            with stages("engine"):
                evaluated = self.evaluate(
                    network_index,
                    [queries[row] for row in rows],
                    [placements[row] for row in rows],
                    [categories[row] for row in rows],
                )
            with stages("encode"):
                self._record(queries, categories, indices, placements, rows, evaluated, vehicles, answers, fleet)
        with stages("encode"):
            for index, fcw in zip(indices, fcw_answers(queries), strict=False):
                answers.documents[index].fcw = fcw

    def evaluate(
        self,
        network_index: int,
        queries: Sequence[DecodedQuery],
        placements: Sequence[Placement],
        categories: Sequence[Category],
    ) -> Evaluated:
        """The engine's answers for placed queries of distinct vehicles of ``categories`` on one network, as columns.

        One vehicle takes the engine's one-vehicle path; more are evaluated as columns in one
        :meth:`csws.engine.Engine.evaluate_fleet`, with no object per vehicle beyond its warning.
        Both give the same answers.
        """
        engine = self.networks[network_index].engine
        if len(queries) == 1:
            answer = engine.evaluate(self.vehicle_input(queries[0], placements[0], categories[0]))
            kind = None if answer.path is None else answer.path.kind
            return Evaluated(
                [answer.vehicle_id], [answer.state], [answer.fault], [answer.warning], [kind], lambda _row: answer.path
            )
        fleet = engine.evaluate_fleet(
            [query.vehicle_id for query in queries],
            categories,
            [query.speed_kmh for query in queries],
            [placement.lane_id for placement in placements],
            [placement.lane_pos_m if placement.lane_id is not None else 0.0 for placement in placements],
            [tuple(query.route) if query.route else None for query in queries],
            timestamp_s=[query.timestamp_s for query in queries],
            age_s=[query.age_s for query in queries],
        )
        kinds: list[PathKind | None] = [None] * len(queries)
        ahead_row = {}
        if fleet.ahead is not None:
            for k, (row, horizon) in enumerate(zip(fleet.active, fleet.ahead.horizons, strict=False)):
                kinds[row] = horizon.kind
                ahead_row[row] = k
        return Evaluated(
            fleet.vehicle_id,
            fleet.state,
            fleet.fault,
            fleet.warning,
            kinds,
            lambda row: fleet.ahead.path_ahead(ahead_row[row]),
        )

    def _record(
        self,
        queries: Sequence[DecodedQuery],
        categories: Sequence[Category],
        indices: Sequence[int],
        placements: Sequence[Placement],
        rows: Sequence[int],
        evaluated: Evaluated,
        vehicles: LoadedVehicles,
        answers: EncodedAnswers,
        fleet: str,
    ) -> None:
        """Note the answered vehicles' lanes and answers in their sessions, and their answers at ``indices[rows]``."""
        for k, (row, vehicle_id, state, fault, warning, kind) in enumerate(
            zip(
                rows,
                evaluated.vehicle_id,
                evaluated.state,
                evaluated.fault,
                evaluated.warning,
                evaluated.path_kind,
                strict=False,
            )
        ):
            placement, query = placements[row], queries[row]
            latest = LatestAnswer(categories[row], query.speed_kmh, int(warning.level), query.timestamp_s)
            vehicles.seen(vehicle_id, placement.lane_id, placement.lane_pos_m, latest)
            index = indices[row]
            path = evaluated.path(k) if warning.triggers else None
            answers.documents[index] = self.encode(
                shown_id(fleet, vehicle_id), state, fault, warning, kind, path, placement
            )
            answers.state[index] = state
            answers.level[index] = warning.level

    def vehicle_input(self, query: DecodedQuery, placement: Placement, category: Category) -> VehicleInput:
        """The engine's input for a placed query of a vehicle of ``category``."""
        matched = placement.lane_id is not None
        return VehicleInput(
            query.vehicle_id,
            category,
            query.speed_kmh,
            placement.lane_id,
            placement.lane_pos_m if matched else 0.0,
            tuple(query.route) if query.route else None,
            query.timestamp_s,
            query.age_s,
        )

    # ------------------------------------------------------------------ answers
    def encode(
        self,
        vehicle_id: str,
        state: SystemState,
        fault: Fault | None,
        warning: CurveWarning,
        path_kind: PathKind | None,
        path: PathAhead | None,
        placement: Placement,
    ) -> msgspec.Struct:
        """The contract's WarningAnswer of an engine's answer (system state, fault, warning, the path
        ahead's kind, and the path itself where the warning has CPOIs to locate) for the vehicle its
        fleet calls ``vehicle_id``, ready for msgspec to write (floats unrounded; the state, level
        and path kind as the enumerations' values).

        Most answers of a fleet are level 0, with no CPOI to locate: the HMI hint is written
        once for all, and only CPOIs that trigger are located.
        """
        fault_text = None
        if fault is not None:
            fault_text = fault.value
            if fault is Fault.NO_MAP_MATCH and placement.reason:
                fault_text = f"{fault_text}: {placement.reason}"
        target, triggers = None, []
        located = warning.triggers  # the target is one of them
        if located:
            places = self.cpoi_positions[placement.network_index].of(
                path, [t.curve_id for t in located], [t.part_index for t in located]
            )
            positions = {id(t): place for t, place in zip(located, places, strict=False)}
            if warning.target is not None:
                target = _trigger(warning.target, positions[id(warning.target)])
            triggers = [_trigger(t, positions[id(t)]) for t in warning.triggers]
        matched = None
        if placement.lane_id is not None:
            matched = _MatchedDocument(placement.lane_id, placement.lane_pos_m, placement.distance_m)
        return _AnswerDocument(
            vehicle_id, state, fault_text, warning.level, target, triggers, matched, path_kind, _hmi_json(warning.hmi)
        )


def _document(model: type) -> type[msgspec.Struct]:
    """A struct with the fields of a contract's model, in its order, to write its JSON with msgspec."""
    return msgspec.defstruct(
        f"{model.__name__}Document", [(name, Any) for name in model.model_fields], gc=False, module=__name__
    )


@dataclass(frozen=True)
class Evaluated:
    """The engine's answers for the queries of one network, as parallel columns in their order.

    Attributes
    ----------
    vehicle_id, state, fault, warning
        As in :class:`csws.engine.Answer`.
    path_kind
        The kind of each vehicle's path ahead, None where none was looked at.
    path
        The path ahead of the vehicle in a row (only asked of vehicles whose warning has CPOIs).
    """

    vehicle_id: Sequence[str]
    state: Sequence[SystemState]
    fault: Sequence[Fault | None]
    warning: Sequence[CurveWarning]
    path_kind: Sequence[PathKind | None]
    path: Callable[[int], PathAhead]


#: An answer's ``fcw`` is left out unless the query had a forward_target: the curve warning's answers stay as they were.
_AnswerDocument = msgspec.defstruct(
    "WarningAnswerDocument",
    [*((name, Any) for name in WarningAnswer.model_fields if name != "fcw"), ("fcw", Any, None)],
    omit_defaults=True,
    gc=False,
    module=__name__,
)
_MatchedDocument = _document(Matched)
_ENCODER = msgspec.json.Encoder()


@dataclass
class EncodedAnswers:
    """The answers of queries, in order (the contract's WarningAnswer each, see :meth:`WarningService.encode`),
    with their system states and warning levels (for the metrics).
    """

    documents: list[msgspec.Struct]
    state: list[SystemState]
    level: list[Level]

    def json(self, index: int) -> bytes:
        """One answer's JSON."""
        return _ENCODER.encode(self.documents[index])

    def batch_json(self) -> bytes:
        """The contract's Answers: ``{"answers": [...]}``."""
        return _ENCODER.encode({"answers": self.documents})


@cache
def _hmi_json(hmi: HmiHint) -> msgspec.Raw:
    """The JSON of an HMI hint (there are three)."""
    return msgspec.Raw(_ENCODER.encode(_document(Hmi)(hmi.visual, hmi.audible)))


def _trigger(trigger: Trigger, point: dict[str, float]) -> dict[str, Any]:
    return {
        "curve_id": trigger.curve_id,
        "part_index": int(trigger.part_index),
        "level": int(trigger.level),
        "distance_m": float(trigger.distance_m),
        "radius_m": float(trigger.radius_m),
        "warning_speed_kmh": float(trigger.warning_speed_kmh),
        "warning_distance_m": float(trigger.warning_distance_m),
        "held": bool(trigger.held),
        "position": point,
    }
