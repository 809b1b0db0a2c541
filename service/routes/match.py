"""``POST /v1/match``: the lanes a whole trace of fixes was driven on, as OSRM's and Valhalla's trace matching.

The trace is matched as one sequence by the service's map matcher (:mod:`csws.road.hmm`): each fix on the
lane the whole trace makes most probable, a fix inside a junction on the connection the later fixes show.
Nothing of a vehicle is read or kept: the trace is all there is.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from fastapi import APIRouter, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import Response
from pydantic import TypeAdapter, ValidationError

from csws.road.hmm import Fixes, SequenceMatches
from csws.road.matching import lane_point
from csws.standard import kmh_to_mps

from ..checks import QueryErrors
from ..deps import CallerDep, ServiceDep, TraceWorkDep
from ..match_schemas import MatchAnswer, Trace
from ..placement import Placer
from .common import BOUNDED, INVALID_BODY, KEYED, json_body, json_response

__all__ = ["router", "match_trace"]

router = APIRouter(tags=["matching"])

#: Validates a trace's JSON body (a 422 naming each bad fix and field).
TRACE_ADAPTER = TypeAdapter(Trace)


def _decoded(body: bytes) -> Trace:
    """The trace of a JSON body; an HTTP 422 naming each problem otherwise (a body that is not JSON too)."""
    try:
        return TRACE_ADAPTER.validate_json(body)
    except ValidationError as exc:
        errors = [{**error, "loc": ("body", *error["loc"])} for error in exc.errors(include_url=False)]
        raise RequestValidationError(errors) from None


def _check(trace: Trace, placer: Placer) -> None:
    """A 422 (:class:`service.checks.QueryErrors`) for a network not served, or lon/lat no named or served
    network can place."""
    lanes = placer.lanes
    if trace.network is not None and trace.network not in lanes.network_index:
        served = ", ".join(sorted(lanes.network_index))
        raise QueryErrors(
            [
                {
                    "loc": ["body", "network"],
                    "msg": f"unknown network {trace.network!r}: served are {served}",
                    "type": "value_error",
                }
            ]
        )
    geographic = lanes.geo_networks if trace.network is None else [lanes.network_index[trace.network]]
    geo_served = [index for index in geographic if index in lanes.geo_networks]
    errors = [
        {
            "loc": ["body", "fixes", index, "position"],
            "msg": "lon/lat needs a geo-referenced network; give x/y in network metres",
            "type": "value_error",
        }
        for index, fix in enumerate(trace.fixes)
        if fix.position.is_geographic and not geo_served
    ]
    if errors:
        raise QueryErrors(errors)


def match_trace(placer: Placer, trace: Trace) -> dict[str, Any]:
    """The matched lane of each fix of ``trace`` (:class:`service.match_schemas.MatchAnswer`) as plain data."""
    _check(trace, placer)
    fixes = trace.fixes
    columns = [
        (
            fix.timestamp_s,
            math.nan if fix.heading_deg is None else fix.heading_deg,
            math.nan if fix.speed_kmh is None else kmh_to_mps(fix.speed_kmh),
            math.nan if fix.accuracy_m is None else fix.accuracy_m,
        )
        for fix in fixes
    ]
    time_s, heading_deg, speed_mps, accuracy_m = (
        np.array(column, dtype=float) for column in zip(*columns, strict=True)
    )
    probes = placer.probes([fix.position for fix in fixes], [trace.network] * len(fixes))
    matched = placer.matcher.match_trace(Fixes(probes, time_s, heading_deg, speed_mps, accuracy_m))
    return {"matched": [_matched_fix(placer, matched, row) for row in range(len(fixes))]}


def _matched_fix(placer: Placer, matched: SequenceMatches, row: int) -> dict[str, Any]:
    """One fix's answer (:class:`service.match_schemas.MatchedFix`)."""
    lane_id, map_index = matched.lane_id[row], int(matched.map_index[row])
    if lane_id is None:
        empty = dict.fromkeys(("network", "lane_id", "edge_id", "lane_pos_m", "distance_m", "point", "placed"))
        return {**empty, "reason": matched.reason[row]}
    network = placer.networks[map_index]
    road_map = network.road_map
    lane_pos_m = float(matched.lane_pos_m[row])
    x, y = lane_point(road_map, lane_id, lane_pos_m)
    point: dict[str, Any] = {"x": x, "y": y, "lon": None, "lat": None}
    if road_map.has_projection:
        point["lon"], point["lat"] = road_map.xy_to_lonlat(x, y)
    distance_m = float(matched.distance_m[row])
    placed = matched.placed[row]
    return {
        "network": network.name,
        "lane_id": lane_id,
        "edge_id": road_map.lane(lane_id).edge_id,
        "lane_pos_m": lane_pos_m,
        "distance_m": distance_m if math.isfinite(distance_m) else None,
        "point": point,
        "placed": None if placed is None else str(placed),
        "reason": None,
    }


def _answer(placer: Placer, body: bytes) -> Response:
    """Decode and match a trace's body (on the traces' thread: a long trace never holds up the warnings)."""
    return json_response(match_trace(placer, _decoded(body)))


@router.post(
    "/v1/match",
    summary="The lanes a trace of fixes was driven on, each fix matched over the whole trace",
    response_model=None,
    responses={200: {"model": MatchAnswer}, **INVALID_BODY, **KEYED, **BOUNDED},
    openapi_extra=json_body(Trace),
)
async def match(request: Request, _principal: CallerDep, service: ServiceDep, traces: TraceWorkDep) -> Response:
    """Match the trace as one sequence (OSRM's ``match``, Valhalla's ``trace_attributes``)."""
    response: Response = await traces.run(_answer, service.placer, await request.body())
    return response
