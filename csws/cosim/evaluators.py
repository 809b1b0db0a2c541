"""Who answers for the fleet: the library in this process, or a running csws service over HTTP.

Both take the same inputs, SUMO's lane id and lane position, speed, route and simulation
time of every vehicle, and return the same :class:`VehicleWarning` records, so a run
gives identical warnings in either mode:

* :class:`LibraryEvaluator` calls :meth:`csws.engine.Engine.evaluate_many` once per step;
* :class:`ServiceEvaluator` sends one ``POST /v1/warnings`` batch per step, the way
  on-board units would ask (``lane_id`` + ``lane_pos_m`` + ``route`` + ``timestamp_s``, so
  the service does no map matching), and reads the answers back.
"""

from __future__ import annotations

import http.client
import json
from dataclasses import dataclass
from typing import Protocol, Sequence
from urllib.parse import urlsplit

from csws.engine import Answer, Engine, VehicleInput
from csws.standard import Level, mps_to_kmh
from csws.warning import Trigger

from .sumo import FleetState

__all__ = [
    "MAX_BATCH",
    "VehicleWarning",
    "Evaluator",
    "LibraryEvaluator",
    "ServiceEvaluator",
    "ServiceError",
]

#: At most this many queries go in one ``POST /v1/warnings`` (the contract's limit).
MAX_BATCH = 10_000


@dataclass(frozen=True)
class VehicleWarning:
    """What the system answered for one vehicle at one step.

    Attributes
    ----------
    vehicle_id
        The vehicle.
    state
        ``off``, ``standby``, ``active`` or ``fault``.
    fault
        The fault's reason, else None.
    level
        0, 1 or 2.
    target
        The target CPOI (3.12), or None.
    triggers
        Every triggering CPOI, nearest first.
    """

    vehicle_id: str
    state: str
    fault: str | None
    level: int
    target: Trigger | None
    triggers: tuple[Trigger, ...]


class Evaluator(Protocol):
    """Answers for every vehicle of a step, in order."""

    def __call__(self, fleet: FleetState) -> list[VehicleWarning]: ...

    def forget(self, vehicle_ids: Sequence[str]) -> None: ...

    def close(self) -> None: ...


def _speeds_kmh(fleet: FleetState) -> list[float]:
    """The fleet's speeds in km/h, as both modes send them."""
    return [float(v) for v in mps_to_kmh(fleet.speed_mps)]


class LibraryEvaluator:
    """The engine in this process: one ``evaluate_many`` per step."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def __call__(self, fleet: FleetState) -> list[VehicleWarning]:
        speeds_kmh = _speeds_kmh(fleet)
        inputs = [
            VehicleInput(vehicle_id, category, speed_kmh, lane_id, float(lane_pos_m), route, fleet.time_s)
            for vehicle_id, category, speed_kmh, lane_id, lane_pos_m, route in zip(
                fleet.vehicle_id, fleet.category, speeds_kmh, fleet.lane_id, fleet.lane_pos_m, fleet.route_edges
            )
        ]
        return [_from_answer(answer) for answer in self.engine.evaluate_many(inputs)]

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        for vehicle_id in vehicle_ids:
            self.engine.forget(vehicle_id)

    def close(self) -> None:
        return None


def _from_answer(answer: Answer) -> VehicleWarning:
    """The record of a library answer."""
    warning = answer.warning
    return VehicleWarning(
        answer.vehicle_id,
        answer.state.value,
        None if answer.fault is None else answer.fault.value,
        int(warning.level),
        warning.target,
        warning.triggers,
    )


class ServiceError(RuntimeError):
    """The service refused a batch or could not be reached."""


class ServiceEvaluator:
    """A csws service over HTTP: one ``POST /v1/warnings`` per step on a kept-alive connection.

    Parameters
    ----------
    url
        The service's base URL, e.g. ``http://127.0.0.1:8000``.
    timeout_s
        How long to wait for an answer, s.
    """

    def __init__(self, url: str, timeout_s: float = 30.0) -> None:
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise ValueError(f"--service must be an http(s) URL such as http://127.0.0.1:8000, got {url!r}")
        connection_type = http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
        self.url = url
        self.path = parts.path.rstrip("/") + "/v1/warnings"
        self.connection = connection_type(parts.hostname, parts.port, timeout=timeout_s)

    def __call__(self, fleet: FleetState) -> list[VehicleWarning]:
        speeds_kmh = _speeds_kmh(fleet)
        queries = [
            {
                "vehicle_id": vehicle_id,
                "category": category,
                "speed_kmh": speed_kmh,
                "lane_id": lane_id,
                "lane_pos_m": float(lane_pos_m),
                "route": list(route),
                "timestamp_s": fleet.time_s,
            }
            for vehicle_id, category, speed_kmh, lane_id, lane_pos_m, route in zip(
                fleet.vehicle_id, fleet.category, speeds_kmh, fleet.lane_id, fleet.lane_pos_m, fleet.route_edges
            )
        ]
        answers = []
        for first in range(0, len(queries), MAX_BATCH):
            answers += self._post({"queries": queries[first:first + MAX_BATCH]})["answers"]
        return [_from_json(answer) for answer in answers]

    def _post(self, body: dict) -> dict:
        """One POST; ServiceError on a refusal, the answer's JSON otherwise."""
        payload = json.dumps(body).encode("utf-8")
        try:
            self.connection.request("POST", self.path, payload, {"Content-Type": "application/json"})
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


def _trigger(record: dict) -> Trigger:
    """A Trigger from the contract's JSON."""
    return Trigger(
        curve_id=record["curve_id"],
        part_index=int(record["part_index"]),
        distance_m=float(record["distance_m"]),
        radius_m=float(record["radius_m"]),
        level=Level(int(record["level"])),
        warning_speed_kmh=float(record["warning_speed_kmh"]),
        warning_distance_m=float(record["warning_distance_m"]),
    )


def _from_json(answer: dict) -> VehicleWarning:
    """The record of a WarningAnswer of the contract."""
    target = answer.get("target")
    return VehicleWarning(
        answer["vehicle_id"],
        answer["state"],
        answer.get("fault"),
        int(answer["level"]),
        None if target is None else _trigger(target),
        tuple(_trigger(t) for t in answer.get("triggers", ())),
    )
