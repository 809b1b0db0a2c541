"""Who answers for the fleet: the library in this process, or a running csws service over HTTP.

Both take the same inputs, SUMO's lane id and lane position, speed, route and simulation
time of every vehicle, and return the same :class:`FleetWarnings`, so a run
gives identical warnings in either mode:

* :class:`LibraryEvaluator` calls :meth:`csws.engine.Engine.evaluate_fleet` once per step;
* :class:`ServiceEvaluator` sends one ``POST /v1/warnings`` batch per step, the way
  on-board units would ask (``lane_id`` + ``lane_pos_m`` + ``route`` + ``timestamp_s``, so
  the service does no map matching), and reads the answers back.
"""

from __future__ import annotations

import http.client
import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, TypedDict
from urllib.parse import urlsplit

from csws.ahead.horizon import BatchAhead, PathAhead
from csws.engine import Engine, TargetColumns
from csws.errors import CswsError
from csws.standard import mps_to_kmh
from csws.state import SystemState

from .sumo import FleetState

__all__ = [
    "MAX_BATCH",
    "FleetWarnings",
    "Evaluator",
    "LibraryEvaluator",
    "ServiceEvaluator",
    "ServiceError",
]

#: At most this many queries go in one ``POST /v1/warnings`` (the contract's limit).
MAX_BATCH = 10_000


@dataclass(frozen=True)
class FleetWarnings:
    """What the system answered for every vehicle of a step, as columns in the fleet's order.

    Columns rather than one record or warning object per vehicle, so that a step of a large
    fleet goes from the engine to the files without per-vehicle objects.

    Attributes
    ----------
    state
        ``off``, ``standby``, ``active`` or ``fault``.
    level
        0, 1 or 2.
    target
        The target CPOI (3.12) of each vehicle, field by field; None where it has no warning.
    entries
        The triggering CPOIs the vehicles are inside (distance 0), in the fleet's order:
        vehicle row, curve id, part index, radius (m), level.
    """

    state: Sequence[str]
    level: list[int]
    target: TargetColumns
    entries: list[tuple[int, str, int, float, int]]

    @classmethod
    def none(cls, count: int) -> FleetWarnings:
        """The answers of ``count`` vehicles that were not evaluated (baseline runs)."""
        return cls([SystemState.OFF] * count, [0] * count, no_targets(count), [])


def no_targets(count: int) -> TargetColumns:
    """The target columns of ``count`` vehicles without a warning: None in every field."""
    return TargetColumns([None] * count, [None] * count, [None] * count, [None] * count, [None] * count)


class Evaluator(Protocol):
    """Answers for every vehicle of a step, in order."""

    def __call__(self, fleet: FleetState) -> FleetWarnings: ...

    def forget(self, vehicle_ids: Sequence[str]) -> None: ...

    def close(self) -> None: ...


def _speeds_kmh(fleet: FleetState) -> list[float]:
    """The fleet's speeds in km/h, as both modes send them."""
    return mps_to_kmh(fleet.speed_mps).tolist()


class LibraryEvaluator:
    """The engine in this process: one ``evaluate_fleet`` per step."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        #: The rows of the last step's vehicles that were active, and their roads ahead in that order.
        self.active: list[int] = []
        self.ahead: BatchAhead | None = None
        self._count = 0
        self._paths_ahead: list[PathAhead | None] | None = []

    @property
    def paths_ahead(self) -> list[PathAhead | None]:
        """Each vehicle's path ahead of the last step (None where not active on the map), for the FCW: built
        when first read after the step, so that a run without the FCW builds no path object per vehicle."""
        if self._paths_ahead is None:
            paths: list[PathAhead | None] = [None] * self._count
            if self.ahead is not None:
                for i, path in zip(self.active, self.ahead.paths_ahead(), strict=False):
                    paths[i] = path
            self._paths_ahead = paths
        return self._paths_ahead

    def __call__(self, fleet: FleetState) -> FleetWarnings:
        answers = self.engine.evaluate_fleet(
            fleet.vehicle_id,
            fleet.category,
            _speeds_kmh(fleet),
            fleet.lane_id,
            fleet.lane_pos_m.tolist(),
            fleet.route_edges,
            timestamp_s=[fleet.time_s] * len(fleet.vehicle_id),
        )
        self.active, self.ahead = answers.active, answers.ahead
        self._count, self._paths_ahead = len(fleet.vehicle_id), None
        return FleetWarnings(answers.state, answers.level, answers.targets(), answers.entries())

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        for vehicle_id in vehicle_ids:
            self.engine.forget(vehicle_id)

    def close(self) -> None:
        return None


class ServiceError(RuntimeError, CswsError):
    """The service refused a batch or could not be reached."""


class ServiceEvaluator:
    """A csws service over HTTP: one ``POST /v1/warnings`` per step on a kept-alive connection.

    Parameters
    ----------
    url
        The service's base URL, e.g. ``http://127.0.0.1:8000``.
    timeout_s
        How long to wait for an answer, s.
    api_key
        The fleet's API key, sent as ``Authorization: Bearer``; None for a service without keys.
    """

    def __init__(self, url: str, timeout_s: float = 30.0, api_key: str | None = None) -> None:
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise ValueError(f"--service must be an http(s) URL such as http://127.0.0.1:8000, got {url!r}")
        connection_type = http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
        self.url = url
        self.path = parts.path.rstrip("/") + "/v1/warnings?atomic=true"  # any refused query is an error here
        self.connection = connection_type(parts.hostname, parts.port, timeout=timeout_s)
        self.headers = {"Content-Type": "application/json"}
        if api_key is not None:
            self.headers["Authorization"] = f"Bearer {api_key}"

    def __call__(self, fleet: FleetState) -> FleetWarnings:
        """The service's answers; a vehicle on no lane (SUMO teleports it) is a map-match fault, as the
        engine answers it in-process, and is not sent: the contract needs a lane or a position."""
        on_lane = [i for i, lane_id in enumerate(fleet.lane_id) if lane_id]
        queries = _queries(fleet, on_lane)
        answered: list[_Answer] = []
        for first in range(0, len(queries), MAX_BATCH):
            answered += self._post({"queries": queries[first : first + MAX_BATCH]})["answers"]
        answers = [_OFF_THE_MAP] * len(fleet.vehicle_id)
        for i, answer in zip(on_lane, answered, strict=False):
            answers[i] = answer
        return _fleet_warnings(answers)

    def _post(self, body: dict[str, list[_Query]]) -> _Batch:
        """One POST; ServiceError on a refusal, the answer's JSON otherwise."""
        payload = json.dumps(body).encode("utf-8")
        try:
            self.connection.request("POST", self.path, payload, self.headers)
            response = self.connection.getresponse()
            content = response.read()
        except (OSError, http.client.HTTPException) as exc:
            self.connection.close()
            raise ServiceError(f"the service at {self.url} cannot be reached: {exc}") from None
        if response.status != 200:
            detail = content.decode("utf-8", "replace").strip().replace("\n", " ")[:300]
            raise ServiceError(f"the service at {self.url} answered HTTP {response.status}: {detail}")
        return json.loads(content)

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        return None  # the service expires its vehicles by itself

    def close(self) -> None:
        self.connection.close()


class _Query(TypedDict):
    """One vehicle's query in a ``POST /v1/warnings`` batch (the fields the co-simulation sends)."""

    vehicle_id: str
    category: str
    speed_kmh: float
    lane_id: str
    lane_pos_m: float
    route: tuple[str, ...]
    timestamp_s: float


class _Target(TypedDict):
    """The target CPOI of an answer (3.12), the fields the co-simulation reads."""

    curve_id: str
    part_index: int
    distance_m: float
    radius_m: float
    warning_speed_kmh: float


class _Trigger(TypedDict):
    """A triggering CPOI of an answer, the fields the co-simulation reads."""

    curve_id: str
    part_index: int
    radius_m: float
    distance_m: float
    level: int


class _Answer(TypedDict):
    """One vehicle's answer, the fields the co-simulation reads."""

    state: str
    level: int
    target: _Target | None
    triggers: list[_Trigger]


class _Batch(TypedDict):
    """The service's answer to one batch: the vehicles' answers in the queries' order."""

    answers: list[_Answer]


def _queries(fleet: FleetState, rows: Sequence[int]) -> list[_Query]:
    """The queries of the fleet's vehicles at ``rows``, as on-board units would send them."""
    speeds_kmh, lane_pos_m = _speeds_kmh(fleet), fleet.lane_pos_m.tolist()
    return [
        {
            "vehicle_id": fleet.vehicle_id[i],
            "category": fleet.category[i],
            "speed_kmh": speeds_kmh[i],
            "lane_id": fleet.lane_id[i],
            "lane_pos_m": lane_pos_m[i],
            "route": fleet.route_edges[i],
            "timestamp_s": fleet.time_s,
        }
        for i in rows
    ]


def _fleet_warnings(answers: Sequence[_Answer]) -> FleetWarnings:
    """The service's answers as the columns the run records: targets field by field, and the
    triggering CPOIs each vehicle is inside (distance 0)."""
    target = no_targets(len(answers))
    entries = []
    for i, answer in enumerate(answers):
        found = answer["target"]
        if found is not None:
            target.curve_id[i], target.part_index[i] = found["curve_id"], found["part_index"]
            target.distance_m[i], target.radius_m[i] = found["distance_m"], found["radius_m"]
            target.warning_speed_kmh[i] = found["warning_speed_kmh"]
        entries += [
            (i, trigger["curve_id"], trigger["part_index"], trigger["radius_m"], trigger["level"])
            for trigger in answer["triggers"]
            if trigger["distance_m"] <= 0.0
        ]
    return FleetWarnings(
        [answer["state"] for answer in answers], [answer["level"] for answer in answers], target, entries
    )


#: The answer for a vehicle on no lane: what the engine answers for it (5.4: fault, no warning).
_OFF_THE_MAP: _Answer = {"state": SystemState.FAULT.value, "level": 0, "target": None, "triggers": []}
