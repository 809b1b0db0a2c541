"""Feeding a running ``csws serve`` with a fleet's trajectory, sampled and measured as a feed says.

:func:`query_fields` reads the service's OpenAPI document for the optional fields a query may carry
(a fix's ``accuracy_m``); :func:`feed_service` sends one feed whole, one ``POST /v1/warnings`` batch
per batch instant, and keeps each answer's level, match and warned curve.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Any

import httpx
import msgspec
import numpy as np

from benchmarks.service import server_timing
from benchmarks.telematics_analysis import Fixes, Noise, noisy_fixes, sample_mask
from benchmarks.telematics_fleet import STEP_S, Trajectories, lonlat

if TYPE_CHECKING:
    from benchmarks.telematics import Feed

__all__ = [
    "Sends",
    "QueryFields",
    "FeedAnswers",
    "AnswersRead",
    "read_answers",
    "query_fields",
    "feed_rows",
    "feed_fixes",
    "feed_columns",
    "feed_service",
    "EPOCH_S",
    "BATCH_S",
]

#: The fleet's clock at the simulation's start (timestamps are this plus the simulation time), s.
EPOCH_S = 1_700_000_000.0
#: A sampled feed's batches: one per second of simulated time.
BATCH_S = 1.0
#: How many progress lines a feed prints.
PROGRESS_LINES = 5


class Sends(StrEnum):
    """What of a receiver's measurements a feed sends: the service map-matches positions, takes lane ids as they are."""

    #: The measured fixes: position, heading and speed, each with the receiver's noise.
    FIXES = "fixes"
    #: The true positions and headings, with the receiver's speeds and drops (what the matcher's rules cost alone).
    EXACT_POSITIONS = "exact positions"
    #: The true lane ids and lane positions, with the receiver's speeds and drops (what matching costs at all).
    EXACT_LANES = "exact lanes"


@dataclass(frozen=True)
class QueryFields:
    """Where the service's query schema takes a fix's ``accuracy_m``: ``"query"``, ``"position"`` or nowhere."""

    accuracy: str | None


@dataclass(frozen=True)
class FeedAnswers:
    """A feed's answers in the order sent (time order).

    Attributes
    ----------
    rows
        The trajectory row each answer is for.
    level
        Each answer's curve warning level.
    matched_lane
        Each answer's matched lane id (None: matched nothing).
    confirmed_lane
        Each answer's fix as the service placed it once the vehicle's next matched fix had arrived (the
        ``confirmed`` of that answer: the matcher's window of one fix), else its own matched lane.
    target_edge
        The edge the warned curve starts on (its id's EDGE of EDGE@POS; None without a warning).
    server_ms
        The service's own time for all the feed's batches, ms.
    """

    rows: np.ndarray
    level: np.ndarray
    matched_lane: np.ndarray
    confirmed_lane: np.ndarray
    target_edge: np.ndarray
    server_ms: float


def query_fields(url: str) -> QueryFields:
    """The optional fix fields the running service's query schema accepts, from its OpenAPI document (the
    ``POST /v1/warnings`` request body, its schemas inline or referred to)."""
    document = httpx.get(f"{url}/openapi.json", timeout=30.0).json()
    body = document["paths"]["/v1/warnings"]["post"]["requestBody"]["content"]["application/json"]["schema"]
    query = _resolved(document, _resolved(document, body)["properties"]["queries"]["items"])
    if "accuracy_m" in query.get("properties", {}):
        return QueryFields("query")
    position = query.get("properties", {}).get("position", {})
    for schema in (position, *position.get("anyOf", ())):
        if "accuracy_m" in _resolved(document, schema).get("properties", {}):
            return QueryFields("position")
    return QueryFields(None)


def _resolved(document: dict, schema: dict) -> dict:
    """A schema with its ``$ref`` (``#/components/schemas/NAME``) followed."""
    while "$ref" in schema:
        schema = document["components"]["schemas"][schema["$ref"].rpartition("/")[2]]
    return schema


def _exact_columns(trajectories: Trajectories, rows: np.ndarray) -> dict[str, list]:
    """Exact lane ids and positions, heading and speed of some rows, as plain lists."""
    return {
        "lane_id": [trajectories.lanes[i] for i in trajectories.lane[rows]],
        "lane_pos_m": np.maximum(trajectories.lane_pos_m[rows], 0.0).tolist(),
        "heading_deg": trajectories.heading_deg[rows].tolist(),
        "speed_kmh": (3.6 * trajectories.speed_mps[rows]).tolist(),
    }


def feed_rows(trajectories: Trajectories, interval_s: float) -> np.ndarray:
    """The trajectory rows a feed with fixes every ``interval_s`` samples, in time order."""
    interval_steps = round(interval_s / STEP_S)
    batch_steps = min(interval_steps, round(BATCH_S / STEP_S))
    return np.flatnonzero(sample_mask(trajectories.step, trajectories.vehicle, interval_steps, batch_steps))


def feed_fixes(trajectories: Trajectories, rows: np.ndarray, noise: Noise, seed: int) -> tuple[np.ndarray, Fixes]:
    """The rows that survive a receiver's drops and their measured fixes in network x/y (the fixes a feed
    sends, before they are turned into lon/lat)."""
    t = trajectories
    fixes = noisy_fixes(
        t.x_m[rows], t.y_m[rows], t.heading_deg[rows], 3.6 * t.speed_mps[rows], noise, np.random.default_rng(seed)
    )
    return rows[fixes.kept], fixes


def _position_columns(
    net: Path, x_m: np.ndarray, y_m: np.ndarray, heading_deg: np.ndarray, speed_kmh: np.ndarray
) -> dict[str, list]:
    """Fixes as sent: positions (lon/lat, or network x/y without a projection), headings and speeds."""
    geo = lonlat(net, x_m, y_m)
    names, values = (("lon", "lat"), geo) if geo is not None else (("x", "y"), (x_m, y_m))
    positions = [
        dict(zip(names, pair, strict=True)) for pair in zip(values[0].tolist(), values[1].tolist(), strict=True)
    ]
    return {"position": positions, "heading_deg": heading_deg.tolist(), "speed_kmh": speed_kmh.tolist()}


def _queries(
    trajectories: Trajectories,
    rows: np.ndarray,
    columns: dict[str, list],
    prefix: str,
    accuracy: tuple[str, float] | None,
) -> list[dict[str, Any]]:
    """The queries of some rows: the vehicle (the feed's own id), category, timestamp and the feed's columns."""
    queries = []
    for index, row in enumerate(rows.tolist()):
        vehicle = trajectories.vehicle[row]
        query = {
            "vehicle_id": f"{prefix}-{trajectories.vehicle_ids[vehicle]}",
            "category": trajectories.categories[vehicle],
            "timestamp_s": EPOCH_S + round(float(trajectories.step[row]) * STEP_S, 1),
        }
        query |= {name: values[index] for name, values in columns.items()}
        if accuracy is not None and accuracy[0] == "query":
            query["accuracy_m"] = accuracy[1]
        elif accuracy is not None:
            query["position"] = {**query["position"], "accuracy_m": accuracy[1]}
        queries.append(query)
    return queries


@dataclass
class AnswersRead:
    """What a feed's answers said so far, in order, and each answer's place by vehicle and fix time."""

    level: list[int] = field(default_factory=list)
    matched: list[str | None] = field(default_factory=list)
    confirmed: list[str | None] = field(default_factory=list)
    target: list[str | None] = field(default_factory=list)
    index: dict[tuple[str, float], int] = field(default_factory=dict)


def read_answers(answers: list[dict], queries: list[dict], read: AnswersRead) -> None:
    """Append each answer's level, matched lane and warned curve's edge; place again the earlier fix it confirms."""
    for answer, query in zip(answers, queries, strict=True):
        read.index[(query["vehicle_id"], query["timestamp_s"])] = len(read.level)
        read.level.append(answer["level"])
        read.matched.append(answer["matched"]["lane_id"] if answer["matched"] else None)
        read.confirmed.append(read.matched[-1])
        curve = answer["target"]["curve_id"] if answer["target"] else None
        read.target.append(curve.rpartition("@")[0] if curve else None)
        confirmed = answer.get("confirmed")
        if confirmed is not None:
            read.confirmed[read.index[(query["vehicle_id"], confirmed["timestamp_s"])]] = confirmed["lane_id"]


def feed_columns(
    net: Path, trajectories: Trajectories, feed: Feed, fields: QueryFields
) -> tuple[np.ndarray, dict[str, list], tuple[str, float] | None]:
    """A feed's rows, in time order, with their columns, and where and what ``accuracy_m`` is sent."""
    rows = feed_rows(trajectories, feed.interval_s)
    if feed.noise is None:
        return rows, _exact_columns(trajectories, rows), None
    kept, fixes = feed_fixes(trajectories, rows, feed.noise, feed.seed)
    if feed.sends is Sends.EXACT_LANES:
        return kept, {**_exact_columns(trajectories, kept), "speed_kmh": fixes.speed_kmh.tolist()}, None
    t = trajectories
    measured = (fixes.x_m, fixes.y_m, fixes.heading_deg)
    exact = (t.x_m[kept], t.y_m[kept], t.heading_deg[kept])
    x_m, y_m, heading_deg = exact if feed.sends is Sends.EXACT_POSITIONS else measured
    columns = _position_columns(net, x_m, y_m, heading_deg, fixes.speed_kmh)
    return kept, columns, (fields.accuracy, feed.noise.position_sigma_m) if fields.accuracy else None


def _send(
    client: httpx.Client,
    trajectories: Trajectories,
    rows: np.ndarray,
    columns: dict[str, list],
    prefix: str,
    accuracy: tuple[str, float] | None,
    progress: Callable[[int, int, int], None],
) -> FeedAnswers:
    """Send some rows, one batch per step that has any, and keep their answers."""
    cuts = np.flatnonzero(np.diff(trajectories.step[rows])) + 1
    bounds = list(zip(np.concatenate(([0], cuts)).tolist(), np.concatenate((cuts, [len(rows)])).tolist(), strict=True))
    read = AnswersRead()
    server_ms = 0.0
    for number, (start, end) in enumerate(bounds, start=1):
        batch = {name: values[start:end] for name, values in columns.items()}
        queries = _queries(trajectories, rows[start:end], batch, prefix, accuracy)
        body = msgspec.json.encode({"queries": queries})
        response = client.post("/v1/warnings", content=body, headers={"content-type": "application/json"})
        response.raise_for_status()
        server_ms += server_timing(response.headers["server-timing"])["csws"]
        read_answers(msgspec.json.decode(response.content)["answers"], queries, read)
        progress(number, len(bounds), end)
    return FeedAnswers(
        rows=rows,
        level=np.asarray(read.level, dtype=np.int8),
        matched_lane=np.asarray(read.matched, dtype=object),
        confirmed_lane=np.asarray(read.confirmed, dtype=object),
        target_edge=np.asarray(read.target, dtype=object),
        server_ms=server_ms,
    )


def feed_service(
    url: str, net: Path, trajectories: Trajectories, feed: Feed, prefix: str, fields: QueryFields, log: Callable
) -> FeedAnswers:
    """Send a feed whole to the service, one batch per instant, and keep its answers."""
    rows, columns, accuracy = feed_columns(net, trajectories, feed, fields)
    started = time.perf_counter()

    def progress(number: int, batches: int, queries: int) -> None:
        if number % max(batches // PROGRESS_LINES, 1) == 0:
            log(
                f"  {feed.name}: {number:,} of {batches:,} batches, {queries:,} queries, "
                f"{time.perf_counter() - started:.0f} s"
            )

    with httpx.Client(base_url=url, timeout=120.0) as client:
        return _send(client, trajectories, rows, columns, prefix, accuracy, progress)
