"""What the served networks cannot answer in a query, found before anything is evaluated (an HTTP 422).

The models check each query alone; :class:`QueryCheck` checks it against the networks: lane and
edge ids, lane positions, lon/lat on networks without a projection, a missing category, and
reports every problem with the index of its query (:class:`QueryErrors`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .decoding import DecodedQuery
from .keys import shown_id
from .networks import ServedNetwork
from .vehicles import LoadedVehicles

__all__ = ["SHOWN_CHARS", "QueryErrors", "QueryCheck", "shown"]

#: A value a message echoes (an unknown edge, lane or network id) is cut to this many characters.
SHOWN_CHARS = 64


def shown(value: str) -> str:
    """``value`` quoted as a message echoes it: cut to :data:`SHOWN_CHARS` characters (an 8 MB id must
    not make an 8 MB answer), the cut marked with an ellipsis."""
    return repr(value) if len(value) <= SHOWN_CHARS else repr(value[:SHOWN_CHARS]) + "..."


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


def _error(loc: Sequence[Any], msg: str) -> dict[str, Any]:
    """One problem, as pydantic reports it."""
    return {"loc": list(loc), "msg": msg, "type": "value_error"}


class QueryCheck:
    """Checks queries against the served networks.

    Parameters
    ----------
    networks
        The served networks.
    """

    def __init__(self, networks: Sequence[ServedNetwork]) -> None:
        self.networks = list(networks)
        self.geo_networks = [i for i, n in enumerate(self.networks) if n.road_map.has_projection]
        self.edge_ids = frozenset().union(*(n.edge_ids for n in self.networks))
        self.network_index = {n.name: i for i, n in enumerate(self.networks)}

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
                (
                    "network",
                    f"unknown network {shown(query.network)}: served are " + ", ".join(sorted(self.network_index)),
                )
            ]
        if query.position is not None and query.position.is_geographic and not self._geographic(query):
            problems.append(
                (
                    "position",
                    "the served networks are not geo-referenced: give the position as x and y in network metres",
                )
            )
        if query.lane_id is not None and query.lane_pos_m is not None:  # they go together (check_located)
            problems += self._lane_problems(query, query.lane_id, query.lane_pos_m, vehicles)
        if query.route:
            known = (
                self.edge_ids if query.network is None else self.networks[self.network_index[query.network]].edge_ids
            )
            unknown = [edge for edge in query.route if edge not in known]
            if unknown:
                where_not = "in no served network" if query.network is None else f"not in network {query.network!r}"
                problems.append(("route", f"unknown edge id {shown(unknown[0])}: {where_not}"))
        return problems

    def _geographic(self, query: DecodedQuery) -> bool:
        """Whether the query's network (or, without one, any served network) is geo-referenced."""
        if query.network is None:
            return bool(self.geo_networks)
        return self.network_index[query.network] in self.geo_networks

    def _lane_problems(
        self, query: DecodedQuery, lane_id: str, lane_pos_m: float, vehicles: LoadedVehicles
    ) -> list[tuple[str, str]]:
        """What is wrong with the lane a query gives: a lane no network (or not its network) has, or a lane
        position beyond the lane's end."""
        network_index = self.lane_network(query, lane_id, vehicles)
        if network_index is None:
            where_not = "in no served network" if query.network is None else f"not in network {query.network!r}"
            return [("lane_id", f"unknown lane id {shown(lane_id)}: {where_not}")]
        length_m = self.networks[network_index].road_map.lane(lane_id).length_m
        if lane_pos_m > length_m:
            return [
                (
                    "lane_pos_m",
                    f"lane position {lane_pos_m:g} m lies beyond the end of lane {shown(lane_id)} "
                    f"({length_m:g} m long)",
                )
            ]
        return []

    def lane_network(self, query: DecodedQuery, lane_id: str, vehicles: LoadedVehicles) -> int | None:
        """The network the lane id ``lane_id`` of a query is taken on: the one it names, else the vehicle's own
        if it has the lane, else the first that has it; None if none has it."""
        if query.network is not None:
            named = self.network_index[query.network]
            return named if self.networks[named].road_map.has_lane(lane_id) else None
        own = vehicles.network_of(query.vehicle_id)
        if self.networks[own].road_map.has_lane(lane_id):
            return own
        return next((i for i, network in enumerate(self.networks) if network.road_map.has_lane(lane_id)), None)
