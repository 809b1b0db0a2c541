"""From validated queries to answers: the checks, the placements, the engines, the answers' JSON.

:class:`WarningService` is what the HTTP endpoints call. For a batch it

1. reads the vehicles of the batch from the state store (:mod:`service.vehicles`);
2. checks what the models cannot (:mod:`service.checks`: a 422 listing every problem);
3. places every query on a lane (:mod:`service.placement`: its given lane, or the map match of its fix);
4. evaluates the vehicles of each network in one :meth:`csws.engine.Engine.evaluate_fleet`;
5. answers the forward collision warning of the queries with objects (:mod:`service.fcw_objects`, its
   memory in the vehicles' sessions) or a forward_target (:mod:`service.fcw`), and the HMI of both;
6. notes the events of the answers that changed a vehicle's level or state (:mod:`service.events`);
7. writes the vehicles' sessions (and events) back to the store, and the answers as the JSON of the HTTP
   contract (:mod:`service.encoding`), or for a caller that sends no JSON (the JT/T 808 gateway) as the
   columns it reads: state, level, the target's V_w and the placement.

A vehicle queried twice in one batch is evaluated in order: the batch is cut into
rounds holding each vehicle at most once.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from typing import Any, cast

import msgspec

from csws.ahead.horizon import PathAhead
from csws.engine import VehicleInput
from csws.road.match_settings import MatchSettings
from csws.standard import Category
from csws.state import Fault, SystemState, overtaken
from csws.warning.rules import CurveWarning, PathKind
from csws.warning.settings import WarningSettings

from .batch_items import UNANSWERABLE_QUERY, ItemErrors, item_error, problems_by_query
from .checks import QueryCheck, QueryErrors
from .decoding import DecodedQuery
from .encoding import EncodedAnswers, encode_answer, hmi_json, matched_documents
from .events import changes, observed_of
from .fcw import combined_hmi, fcw_answers
from .fcw_objects import object_fcw
from .fcw_settings import FleetFcwSettings
from .horizon import CpoiPositions
from .keys import shown_id, vehicle_key
from .networks import ServedNetwork
from .placement import LanePoints, Placement, Placer
from .sessions import LatestAnswer
from .timing import UNTIMED, Stages
from .vehicles import LoadedVehicles, VehicleRegistry
from .warning_settings import FleetWarningSettings

__all__ = ["QueryErrors", "Placement", "Evaluated", "EncodedAnswers", "WarningService"]


def _of_vehicle(query: DecodedQuery, vehicle_id: str) -> DecodedQuery:
    """The query as asked for the vehicle ``vehicle_id`` (a decoded query is a msgspec struct)."""
    return cast(DecodedQuery, msgspec.structs.replace(cast(msgspec.Struct, query), vehicle_id=vehicle_id))


def _category(query: DecodedQuery, vehicles: LoadedVehicles, fleet_first: bool = False) -> Category:
    """The query's category, else the one its fleet set (the checks made sure one of them is there); with
    ``fleet_first``, the one its fleet set, else the query's."""
    category = vehicles.category(query.vehicle_id) if fleet_first or query.category is None else None
    category = category if category is not None else query.category
    assert category is not None  # a query without one was refused (service.checks)
    return category


def _late(timestamp_s: float | None, newest: LatestAnswer | None) -> bool:
    """Whether a fix was taken before the newest one answered for its vehicle (a message that came late), by at most
    :data:`csws.state.CLOCK_JUMP_S` (further back, the vehicle's clock started again): the vehicle's place and latest
    answer (the live map's) stay those of the newest fix, as its map matching sequence does (:mod:`csws.road.hmm`)."""
    if timestamp_s is None or newest is None or newest.timestamp_s is None:
        return False
    return bool(overtaken(newest.timestamp_s, timestamp_s))


def _event_time(query: DecodedQuery, now_s: float) -> float:
    """The time of the events of a query's answer: its fix's timestamp, else the service's clock ``now_s``."""
    return query.timestamp_s if query.timestamp_s is not None else now_s


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
    fcw_settings
        The forward collision warning's settings per fleet and category (default: the library's by category).
    warning_settings
        The curve warning's update period and release rule per fleet (default: the engines' for every fleet).
    """

    def __init__(
        self,
        networks: Sequence[ServedNetwork],
        registry: VehicleRegistry,
        match_settings: MatchSettings,
        fcw_settings: FleetFcwSettings | None = None,
        warning_settings: FleetWarningSettings | None = None,
    ) -> None:
        self.networks = list(networks)
        self.registry = registry
        self.fcw_settings = fcw_settings if fcw_settings is not None else FleetFcwSettings()
        self.warning_settings = warning_settings
        self.cpoi_positions = [CpoiPositions(network) for network in self.networks]
        self.lane_points = [LanePoints(network.road_map) for network in self.networks]
        self.checks = QueryCheck(self.networks)
        self.placer = Placer(self.checks, match_settings)

    def answer(
        self,
        queries: Sequence[DecodedQuery | None],
        loc: Sequence[Any] = ("body", "queries"),
        fleet: str = "",
        stages: Stages = UNTIMED,
        errors: ItemErrors | None = None,
        documents: bool = True,
        fleet_category_first: bool = False,
    ) -> EncodedAnswers:
        """The answers of ``queries`` of ``fleet``'s vehicles (:func:`service.keys.vehicle_key`), in order, as JSON.

        The vehicles are read from the state store, answered, and their sessions written back
        (:meth:`service.vehicles.VehicleRegistry.transact`); the time of each stage is counted in
        ``stages``. With ``errors`` (a batch answered per query, :mod:`service.batch_items`), the queries
        that are None are those already in it, and each query the networks cannot answer goes into it
        instead of raising: neither is evaluated, nor is its vehicle's session touched. Without ``documents``,
        the answers are their columns (state, level, V_w, placement) and only the answers whose events or
        forward collision warning need one get their document: for a caller that sends no JSON. With
        ``fleet_category_first`` (a JT/T 808 terminal's reports, which carry its terminal list's category), a
        category the fleet set for a vehicle (``PUT /v1/vehicles/{id}``) wins over the query's: one vehicle has
        one category whichever way it talks. Each answer's category is in ``category``.

        Raises
        ------
        QueryErrors
            Without ``errors``: if any query names an unknown lane or edge, lies beyond its lane,
            sends lon/lat to networks without a projection, or has no category; nothing is
            evaluated then.
        StoreUnavailable
            When the state store cannot be read or written now.
        """
        named = cast(list[DecodedQuery], queries)  # None only at the indices of ``errors``, never read
        if fleet:
            named = [
                cast(DecodedQuery, query) if query is None else _of_vehicle(query, vehicle_key(fleet, query.vehicle_id))
                for query in queries
            ]
        answers = EncodedAnswers.of_count(len(queries), documents)

        def answer_vehicles(vehicles: LoadedVehicles, vehicle_ids: Collection[str]) -> None:
            with stages("check"):
                indices = [i for i, query in enumerate(named) if query is not None and query.vehicle_id in vehicle_ids]
                indices = self._checked(named, vehicles, loc, fleet, indices, errors)
            for round_indices in _rounds(named, indices):
                self._answer_round(
                    [named[i] for i in round_indices],
                    round_indices,
                    vehicles,
                    answers,
                    fleet,
                    stages,
                    fleet_category_first,
                )

        self.registry.transact({query.vehicle_id for query in named if query is not None}, answer_vehicles, stages)
        return answers

    def _checked(
        self,
        queries: Sequence[DecodedQuery],
        vehicles: LoadedVehicles,
        loc: Sequence[Any],
        fleet: str,
        indices: list[int],
        errors: ItemErrors | None,
    ) -> list[int]:
        """The ``indices`` of the queries the networks can answer; the others raise :class:`QueryErrors`, or with
        ``errors`` go into it as ``unanswerable_query`` entries."""
        try:
            self.check(queries, vehicles, loc, fleet, indices)
        except QueryErrors as exc:
            if errors is None:
                raise
            unanswerable = problems_by_query(exc.errors)
            for index, problems in unanswerable.items():
                errors[index] = item_error(
                    index, shown_id(fleet, queries[index].vehicle_id), UNANSWERABLE_QUERY, problems
                )
            return [index for index in indices if index not in unanswerable]
        return indices

    def check(
        self,
        queries: Sequence[DecodedQuery],
        vehicles: LoadedVehicles,
        loc: Sequence[Any] = ("body", "queries"),
        fleet: str = "",
        indices: Sequence[int] | None = None,
    ) -> None:
        """Raise :class:`QueryErrors` listing what in ``queries`` the networks cannot answer
        (:meth:`service.checks.QueryCheck.check`)."""
        self.checks.check(queries, vehicles, loc, fleet, indices)

    def place(self, queries: Sequence[DecodedQuery], vehicles: LoadedVehicles) -> list[Placement]:
        """Where each query is (:meth:`service.placement.Placer.place`)."""
        return self.placer.place(queries, vehicles)

    def _answer_round(
        self,
        queries: Sequence[DecodedQuery],
        indices: Sequence[int],
        vehicles: LoadedVehicles,
        answers: EncodedAnswers,
        fleet: str,
        stages: Stages,
        fleet_category_first: bool = False,
    ) -> None:
        """Answer queries of distinct vehicles of ``fleet`` into ``answers[indices]`` (``fleet_category_first``: as
        :meth:`answer` takes it)."""
        with stages("match"):
            placements = self.place(queries, vehicles)
        by_network: dict[int, list[int]] = defaultdict(list)
        for row, (query, placement) in enumerate(zip(queries, placements, strict=False)):
            vehicles.place(query.vehicle_id, placement.network_index)
            by_network[placement.network_index].append(row)
        categories = [_category(query, vehicles, fleet_category_first) for query in queries]
        paths: list[PathAhead | None] = [None] * len(queries)
        for network_index, rows in by_network.items():
            with stages("engine"):
                evaluated = self.evaluate(
                    network_index,
                    [queries[row] for row in rows],
                    [placements[row] for row in rows],
                    [categories[row] for row in rows],
                    fleet,
                )
            with stages("encode"):
                self._record(queries, categories, indices, placements, rows, evaluated, vehicles, answers, fleet)
            for k, row in enumerate(rows):
                if queries[row].objects is not None:
                    paths[row] = evaluated.path(k)
        with stages("fcw"):
            self._answer_fcw(queries, indices, categories, paths, vehicles, answers, fleet)

    def _answer_fcw(
        self,
        queries: Sequence[DecodedQuery],
        indices: Sequence[int],
        categories: Sequence[Category],
        paths: Sequence[PathAhead | None],
        vehicles: LoadedVehicles,
        answers: EncodedAnswers,
        fleet: str,
    ) -> None:
        """The forward collision warning of the round's queries with objects or a forward_target, into their
        answers' ``fcw`` and ``hmi``; the FCW memory of those with objects into their sessions."""
        if all(query.objects is None and query.forward_target is None for query in queries):
            return
        settings = [self.fcw_settings.of(fleet, category) for category in categories]
        fcw = fcw_answers(queries, settings)
        rows = [row for row, query in enumerate(queries) if query.objects is not None]
        now_s = time.time()
        if rows:
            sessions = [vehicles.sessions[queries[row].vehicle_id] for row in rows]
            found, kept = object_fcw(
                [queries[row] for row in rows],
                [settings[row] for row in rows],
                [session.fcw for session in sessions],
                [paths[row] for row in rows],
                now_s,
            )
            for row, session, found_answer, memory in zip(rows, sessions, found, kept, strict=True):
                fcw[row], session.fcw = found_answer, memory
        for query, index, answer in zip(queries, indices, fcw, strict=True):
            if answer is not None:
                document = answers.documents[index]
                document.fcw = answer
                if answer["level"] > 0:
                    document.hmi = hmi_json(combined_hmi(document.level, answer["level"]))
                if answer["level"] != vehicles.trail(query.vehicle_id).fcw_level:
                    observed = observed_of(document, _event_time(query, now_s))
                    vehicles.observe_fcw(query.vehicle_id, answer["level"], answer.get("target_id"), observed)

    def warning_of(self, fleet: str, network_index: int) -> WarningSettings:
        """The curve warning's settings of ``fleet``'s vehicles on a network: its engine's, with what the fleet's
        warning settings pin (:mod:`service.warning_settings`)."""
        if self.warning_settings is None:
            return self.networks[network_index].engine.settings.warning
        return self.warning_settings.of(fleet)

    def evaluate(
        self,
        network_index: int,
        queries: Sequence[DecodedQuery],
        placements: Sequence[Placement],
        categories: Sequence[Category],
        fleet: str = "",
    ) -> Evaluated:
        """The engine's answers for placed queries of distinct vehicles of ``categories`` of ``fleet`` on one network,
        as columns, with the fleet's warning settings (:meth:`warning_of`).

        One vehicle takes the engine's one-vehicle path; more are evaluated as columns in one
        :meth:`csws.engine.Engine.evaluate_fleet`, with no object per vehicle beyond its warning.
        Both give the same answers.
        """
        engine = self.networks[network_index].engine
        warning = self.warning_of(fleet, network_index)
        if len(queries) == 1:
            answer = engine.evaluate(self.vehicle_input(queries[0], placements[0], categories[0]), warning)
            kind = None if answer.path is None else answer.path.kind
            return Evaluated(
                [answer.vehicle_id], [answer.state], [answer.fault], [answer.warning], [kind], lambda _row: answer.path
            )
        answers = engine.evaluate_fleet(
            [query.vehicle_id for query in queries],
            categories,
            [query.speed_kmh for query in queries],
            [placement.path_lane_id for placement in placements],
            [placement.path_lane_pos_m if placement.path_lane_id is not None else 0.0 for placement in placements],
            [tuple(query.route) if query.route else None for query in queries],
            timestamp_s=[query.timestamp_s for query in queries],
            age_s=[query.age_s for query in queries],
            warning=warning,
        )
        kinds: list[PathKind | None] = [None] * len(queries)
        ahead_row = {}
        ahead = answers.ahead
        if ahead is None:  # no vehicle looked ahead
            return Evaluated(
                answers.vehicle_id, answers.state, answers.fault, answers.warning, kinds, lambda _row: None
            )
        for k, (row, horizon) in enumerate(zip(answers.active, ahead.horizons, strict=True)):
            kinds[row] = horizon.kind
            ahead_row[row] = k
        return Evaluated(
            answers.vehicle_id,
            answers.state,
            answers.fault,
            answers.warning,
            kinds,
            lambda row: ahead.path_ahead(ahead_row[row]) if row in ahead_row else None,
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
        """Note the answered vehicles' lanes and answers in their sessions, and their answers at ``indices[rows]``
        (the rows of one network): the columns of each, and the documents of those that need one."""
        answered_at_s = time.time()
        documented: list[tuple[int, bool]] = []  # (k, whether its answer changes its events' trail)
        for k, (row, vehicle_id, state, fault, warning) in enumerate(
            zip(rows, evaluated.vehicle_id, evaluated.state, evaluated.fault, evaluated.warning, strict=False)
        ):
            placement, query = placements[row], queries[row]
            target = warning.target
            latest = LatestAnswer(
                categories[row],
                query.speed_kmh,
                int(warning.level),
                query.timestamp_s,
                query.heading_deg,
                target.curve_id if target is not None else None,
                target.warning_speed_kmh if target is not None else None,
                answered_at_s,
            )
            if _late(query.timestamp_s, vehicles.sessions[vehicle_id].latest):  # the newest stays the vehicle's
                trail = vehicles.seen(vehicle_id, None).trail
            else:
                trail = vehicles.seen(vehicle_id, placement.lane_id, placement.lane_pos_m, latest).trail
            index = indices[row]
            answers.state[index], answers.level[index], answers.placement[index] = state, warning.level, placement
            answers.category[index] = categories[row]
            answers.warning_speed_kmh[index] = float(target.warning_speed_kmh) if target is not None else None
            changed = changes(trail, latest.level, state, fault is Fault.NO_MAP_MATCH)
            if changed or answers.with_documents or query.objects is not None or query.forward_target is not None:
                documented.append((k, changed))
        if documented:
            self._document(queries, indices, placements, rows, evaluated, documented, answers, fleet)
        for k, changed in documented:
            if changed:
                index, query = indices[rows[k]], queries[rows[k]]
                observed = observed_of(answers.documents[index], _event_time(query, answered_at_s))
                vehicles.observe(evaluated.vehicle_id[k], observed)

    def _document(
        self,
        queries: Sequence[DecodedQuery],
        indices: Sequence[int],
        placements: Sequence[Placement],
        rows: Sequence[int],
        evaluated: Evaluated,
        documented: Sequence[tuple[int, bool]],
        answers: EncodedAnswers,
        fleet: str,
    ) -> None:
        """The contract's WarningAnswer of the ``documented`` answers (their k among ``rows``, of one network),
        placed at their points in one interpolation, into ``answers.documents``."""
        network_index = placements[rows[0]].network_index
        matched = matched_documents(
            self.networks[network_index],
            self.lane_points[network_index],
            [placements[rows[k]] for k, _ in documented],
        )
        for (k, _), matched_document in zip(documented, matched, strict=True):
            row, warning = rows[k], evaluated.warning[k]
            answers.documents[indices[row]] = encode_answer(
                self.cpoi_positions[network_index],
                shown_id(fleet, evaluated.vehicle_id[k]),
                evaluated.state[k],
                evaluated.fault[k],
                warning,
                evaluated.path_kind[k],
                evaluated.path(k) if warning.triggers else None,
                placements[row],
                matched_document,
            )

    def vehicle_input(self, query: DecodedQuery, placement: Placement, category: Category) -> VehicleInput:
        """The engine's input for a placed query of a vehicle of ``category``."""
        matched = placement.path_lane_id is not None
        return VehicleInput(
            query.vehicle_id,
            category,
            query.speed_kmh,
            placement.path_lane_id,
            placement.path_lane_pos_m if matched else 0.0,
            tuple(query.route) if query.route else None,
            query.timestamp_s,
            query.age_s,
        )

    # ------------------------------------------------------------------ answers


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
        The path ahead of the vehicle in a row, None where it did not look ahead.
    """

    vehicle_id: Sequence[str]
    state: Sequence[SystemState]
    fault: Sequence[Fault | None]
    warning: Sequence[CurveWarning]
    path_kind: Sequence[PathKind | None]
    path: Callable[[int], PathAhead | None]
