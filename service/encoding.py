"""The answers as the JSON of the HTTP contract, written by msgspec (floats unrounded).

Each answer is a struct with the fields of the contract's :class:`service.answer_schemas.WarningAnswer`,
in its order (:func:`encode_answer`); :class:`EncodedAnswers` holds a request's answers in order and
writes one of them, or all as the contract's ``Answers``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any, cast

import msgspec
from pydantic import BaseModel

from csws.ahead.horizon import PathAhead
from csws.standard import Category, Level
from csws.state import Fault, SystemState
from csws.warning.rules import CurveWarning, HmiHint, PathKind, Trigger

from .answer_schemas import ConfirmedFix, Hmi, Matched, WarningAnswer
from .horizon import CpoiPositions, positions
from .networks import ServedNetwork
from .placement import LanePoints, Placement

__all__ = ["EncodedAnswers", "encode_answer", "hmi_json", "matched_documents"]


def _document(model: type[BaseModel]) -> type[msgspec.Struct]:
    """A struct with the fields of a contract's model, in its order, to write its JSON with msgspec."""
    return msgspec.defstruct(
        f"{model.__name__}Document", [(name, Any) for name in model.model_fields], gc=False, module=__name__
    )


#: The fields an answer leaves out where they are null: ``confirmed`` (a fix matched on the map that continues a
#: sequence) and ``fcw`` (a query with objects or a forward_target); the other answers stay as they were.
_OPTIONAL = ("confirmed", "fcw")
_AnswerDocument = msgspec.defstruct(
    "WarningAnswerDocument",
    [
        *((name, Any) for name in WarningAnswer.model_fields if name not in _OPTIONAL),
        *((name, Any, None) for name in _OPTIONAL),
    ],
    omit_defaults=True,
    gc=False,
    module=__name__,
)
_MatchedDocument = _document(Matched)
_ConfirmedDocument = _document(ConfirmedFix)
_ENCODER = msgspec.json.Encoder()


@dataclass
class EncodedAnswers:
    """The answers of queries, in order (the contract's WarningAnswer each, see :meth:`WarningService.answer`),
    with their system states and warning levels (for the metrics), their target's V_w and their placements.

    Attributes
    ----------
    documents
        The answers as msgspec structs of the contract, None until answered (and, without
        ``with_documents``, None where no event or forward collision warning needed one).
    state, level
        Each answer's system state and curve warning level.
    warning_speed_kmh
        Each answer's target curve's V_w at the target's level (3.12), km/h: the target's
        ``warning_speed_kmh`` of its document; None without a target.
    placement
        Where each query was placed, None until answered.
    category
        The category each query was answered for, None until answered.
    with_documents
        Whether every answer gets its document (the HTTP contract), or only those an event or the
        forward collision warning needs (a gateway reading the columns alone).
    """

    documents: list[Any]
    state: list[SystemState]
    level: list[Level]
    warning_speed_kmh: list[float | None]
    placement: list[Placement | None]
    category: list[Category | None]
    with_documents: bool = True

    @classmethod
    def of_count(cls, count: int, with_documents: bool = True) -> EncodedAnswers:
        """The answers of ``count`` queries before any is answered (off, level 0)."""
        return cls(
            [None] * count, [SystemState.OFF] * count, [Level.NONE] * count, [None] * count, [None] * count,
            [None] * count, with_documents,
        )  # fmt: skip

    def json(self, index: int) -> bytes:
        """One answer's JSON."""
        return _ENCODER.encode(self.documents[index])

    def batch_json(self) -> bytes:
        """The contract's Answers: ``{"answers": [...]}``."""
        return _ENCODER.encode({"answers": self.documents})


@cache
def hmi_json(hmi: HmiHint) -> msgspec.Raw:
    """The JSON of an HMI hint (there are five: the curve warning's three, the FCW's two)."""
    return msgspec.Raw(_ENCODER.encode(_document(Hmi)(hmi.visual, hmi.audible)))


def _trigger(trigger: Trigger, point: dict[str, float], slopes: tuple[float | None, float | None]) -> dict[str, Any]:
    """A CPOI that triggers, as the contract's Trigger, at ``point``, its curve's grade and superelevation
    ``slopes`` (:meth:`service.horizon.CpoiPositions.slopes`)."""
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
        "grade_pct": slopes[0],
        "superelevation_pct": slopes[1],
    }


def matched_documents(
    network: ServedNetwork, lane_points: LanePoints, placements: Sequence[Placement]
) -> list[msgspec.Struct | None]:
    """The contract's Matched of placements on one network (None where nothing matched): the lane, the
    network, the street's name and road type of the lane's edge, and the point the fix was placed at
    (x, y, and lon, lat on a geo-referenced network), all points interpolated and projected at once."""
    rows = [row for row, placement in enumerate(placements) if placement.lane_id is not None]
    documents: list[msgspec.Struct | None] = [None] * len(placements)
    if not rows:
        return documents
    lane_ids = [cast(str, placements[row].lane_id) for row in rows]
    road_map = network.road_map
    for row, lane_id, point in zip(rows, lane_ids, _placed_points(network, lane_points, placements, rows), strict=True):
        placement, lane = placements[row], road_map.lane(lane_id)
        documents[row] = _MatchedDocument(
            lane_id,
            placement.lane_pos_m,
            placement.distance_m,
            network.name,
            lane.street_name or None,
            lane.road_type or None,
            point,
        )
    return documents


def _placed_points(
    network: ServedNetwork, lane_points: LanePoints, placements: Sequence[Placement], rows: Sequence[int]
) -> list[dict[str, float]]:
    """The points of the placements ``rows`` (on lanes) as the contract's positions: one in plain floats, the
    one-vehicle answer's fast path, more in one interpolation and one projection."""
    if len(rows) == 1:
        placement = placements[rows[0]]
        x, y = lane_points.point(cast(str, placement.lane_id), placement.lane_pos_m)
        if not network.road_map.has_projection:
            return [{"x": x, "y": y}]
        lon, lat = network.road_map.xy_to_lonlat(x, y)
        return [{"x": x, "y": y, "lon": lon, "lat": lat}]
    lane_ids = [cast(str, placements[row].lane_id) for row in rows]
    return positions(network, lane_points.points(lane_ids, [placements[row].lane_pos_m for row in rows]))


def encode_answer(
    cpoi_positions: CpoiPositions,
    vehicle_id: str,
    state: SystemState,
    fault: Fault | None,
    warning: CurveWarning,
    path_kind: PathKind | None,
    path: PathAhead | None,
    placement: Placement,
    matched: msgspec.Struct | None,
) -> msgspec.Struct:
    """The contract's WarningAnswer of an engine's answer (system state, fault, warning, the path
    ahead's kind, and the path itself where the warning has CPOIs to locate, placed by the network's
    ``cpoi_positions``) for the vehicle its fleet calls ``vehicle_id``, placed at ``placement`` (its
    :func:`matched_documents`: ``matched``), ready for msgspec to write
    (floats unrounded; the state, level and path kind as the enumerations' values).

    Most answers of a fleet are level 0, with no CPOI to locate: the HMI hint is written
    once for all, and only CPOIs that trigger are located.
    """
    fault_text = fault_code = None
    if fault is not None:
        fault_text, fault_code = fault.value, fault.code
        if fault is Fault.NO_MAP_MATCH and placement.reason:
            fault_text = f"{fault_text}: {placement.reason}"
    target, triggers = None, []
    located = warning.triggers  # the target is one of them
    if located and path is not None:  # a warning with CPOIs comes with its path
        places = cpoi_positions.of(path, [t.curve_id for t in located], [t.part_index for t in located])
        positions = {id(t): place for t, place in zip(located, places, strict=True)}
        if warning.target is not None:
            target = _trigger(
                warning.target, positions[id(warning.target)], cpoi_positions.slopes(warning.target.curve_id)
            )
        triggers = [_trigger(t, positions[id(t)], cpoi_positions.slopes(t.curve_id)) for t in warning.triggers]
    return _AnswerDocument(
        vehicle_id=vehicle_id,
        state=state,
        fault=fault_text,
        fault_code=fault_code,
        level=warning.level,
        target=target,
        triggers=triggers,
        matched=matched,
        path_kind=path_kind,
        hmi=hmi_json(warning.hmi),
        confirmed=None if placement.confirmed is None else _ConfirmedDocument(*placement.confirmed),
    )
