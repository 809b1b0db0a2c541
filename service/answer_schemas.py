"""The HTTP contract's answers as pydantic models: what a warning, a batch and a vehicle's state look like.

They are documented here for the OpenAPI schema, every field described and every category an
enumeration, so that an on-board unit can code against them; the service writes the answers as
plain JSON without re-validating them (:mod:`service.encoding`, :mod:`service.answers`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from csws.standard import Category

from .batch_schemas import BatchItemError

__all__ = [
    "FaultCode",
    "HmiAudible",
    "HmiVisual",
    "PathKindName",
    "SystemStateName",
    "XY",
    "Trigger",
    "Matched",
    "Hmi",
    "FcwAnswer",
    "WarningAnswer",
    "Answers",
    "VehicleState",
]

#: A system state (T/ITS 0091-2018 5.2-5.4; GB/T 33577 4.3 for the FCW): :class:`csws.state.SystemState`.
SystemStateName = Literal["off", "standby", "active", "fault"]
#: Why the state is fault, stable: :attr:`csws.state.Fault.code`.
FaultCode = Literal["no_map", "no_map_match", "stale_input", "invalid_input"]
#: How the path ahead was found: :class:`csws.warning.rules.PathKind`.
PathKindName = Literal["route", "predicted"]
#: The visual cues of the HMI hints (5.5.1; GB/T 33577 4.5.2): :class:`csws.warning.rules.HmiHint`,
#: :data:`service.fcw.FCW_HMI_HINTS`.
HmiVisual = Literal[
    "curve-warning-amber", "curve-warning-red-flashing", "forward-collision-amber", "forward-collision-red-flashing"
]
#: The audible cues of the HMI hints.
HmiAudible = Literal["warning-tone", "collision-tone"]


class XY(BaseModel):
    """A point in network metres, with lon/lat on geo-referenced networks."""

    x: float = Field(description="network x, m")
    y: float = Field(description="network y, m")
    lon: float | None = Field(default=None, description="longitude, degrees (WGS84); null on networks without one")
    lat: float | None = Field(default=None, description="latitude, degrees (WGS84); null on networks without one")


class Trigger(BaseModel):
    """A CPOI (3.11) whose warning condition (6.1) holds."""

    curve_id: str = Field(
        description="the curve: edge@position of its start (to the metre), the same on every lane of the road"
    )
    part_index: int = Field(description="constant-radius part within the curve (0 for a single curve)")
    level: Literal[1, 2] = Field(description="the warning level whose condition holds (6.1: Table 1 or Table 2)")
    distance_m: float = Field(description="distance S along the path to the CPOI, m (0 inside the part)")
    radius_m: float = Field(description="radius R of the part, m")
    warning_speed_kmh: float = Field(description="V_w of the level at R, km/h (Tables 1-2)")
    warning_distance_m: float = Field(description="S_w of formula (1), m")
    held: bool = Field(
        default=False,
        description="kept on by the release rule (1 km/h below V_w, at least 1 s, off behind the curve), "
        "not required by 6.1 now",
    )
    position: XY = Field(description="the CPOI: first point of the part")
    grade_pct: float | None = Field(
        default=None,
        description="the curve's mean grade in the driving direction, per cent (uphill positive), on a network "
        "imported from OpenDRIVE; null elsewhere. Information beside V_w and S_w, which stay the standard's "
        "(docs/road-model.md: how a grade would change S_w)",
    )
    superelevation_pct: float | None = Field(
        default=None,
        description="the curve's mean cross slope toward the inside of the turn, per cent (the banking that helps "
        "positive), on a network imported from OpenDRIVE; null elsewhere. Information beside V_w, which stays the "
        "standard's (docs/road-model.md: how banking would change V_w)",
    )


class Matched(BaseModel):
    """The lane the query was placed on."""

    lane_id: str = Field(description="SUMO lane id")
    lane_pos_m: float = Field(description="position along the lane, m")
    distance_m: float = Field(description="distance from the position to the lane, m (0 without a position)")
    network: str = Field(description="the served network of the lane (its file name without .net.xml)")
    street_name: str | None = Field(
        description="the street's name (the SUMO edge's name, from OpenStreetMap); null where the network has none"
    )
    road_type: str | None = Field(
        description="the road type (the SUMO edge's type, e.g. highway.primary); null where the network has none"
    )
    position: XY = Field(description="the point of the lane at lane_pos_m, where the fix was placed")


class ConfirmedFix(BaseModel):
    """The vehicle's last matched fix as this fix confirms it (the matcher's window of one fix; docs/service.md,
    "Map matching"): a fix inside a junction, answered on the road's continuation while its turn was not shown,
    lies on the connection the vehicle took once the next fix shows it."""

    timestamp_s: float = Field(description="when that fix was taken, s (its timestamp_s, else answer time less age_s)")
    network: str = Field(description="the served network of the lane")
    lane_id: str = Field(description="SUMO lane id, on the path this fix makes most probable")
    lane_pos_m: float = Field(description="position along the lane, m")
    revised: bool = Field(description="true where that lane is not the one the fix was answered with")


class Hmi(BaseModel):
    """How to present the answer's most urgent warning (5.5.1: the levels told apart; docs/service.md): null and
    null where nothing is to be presented."""

    visual: HmiVisual | None = Field(
        description="the visual cue: the curve warning's level 1 amber or level 2 red flashing, or the forward "
        "collision warning's (service.fcw.combined_hmi); null for none"
    )
    audible: HmiAudible | None = Field(
        description="the audible cue: the curve warning's level 2 tone or the collision warning's; null for none"
    )


class FcwAnswer(BaseModel):
    """The forward collision warning of a query with objects or a forward_target (GB/T 33577; docs/fcw.md)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "state": "active",
                    "level": 1,
                    "ttc_s": 2.5,
                    "ettc_s": 2.5,
                    "a_req_mps2": 4.62,
                    "target_id": None,
                    "clearance_m": 30.0,
                }
            ]
        }
    )

    state: SystemStateName = Field(description="4.3: active between V_min and V_max")
    level: Literal[0, 1, 2] = Field(description="0 none, 1 preliminary warning, 2 collision warning")
    ttc_s: float | None = Field(description="TTC, formula (2), s; null where no collision follows")
    ettc_s: float | None = Field(description="ETTC, formula (3), s; null where no collision follows")
    a_req_mps2: float | None = Field(
        description="a_req, formula (4), m/s^2; null where the reaction uses up the clearance"
    )
    target_id: int | None = Field(
        default=None, description="the target among the objects (the most demanding in the path); null otherwise"
    )
    clearance_m: float | None = Field(default=None, description="the target's clearance x_c, m; null without one")


class WarningAnswer(BaseModel):
    """The system's answer for one query."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "vehicle_id": "truck-17",
                    "state": "active",
                    "fault": None,
                    "level": 2,
                    "target": {
                        "curve_id": "curve@100",
                        "part_index": 0,
                        "level": 2,
                        "distance_m": 95.0,
                        "radius_m": 120.0,
                        "warning_speed_kmh": 58.0,
                        "warning_distance_m": 63.2,
                        "held": False,
                        "position": {"x": 1000.0, "y": 0.0},
                        "grade_pct": None,
                        "superelevation_pct": None,
                    },
                    "triggers": [],
                    "matched": {
                        "lane_id": "curve_0",
                        "lane_pos_m": 5.0,
                        "distance_m": 0.3,
                        "network": "t7_left",
                        "street_name": None,
                        "road_type": None,
                        "position": {"x": 1005.0, "y": 0.1},
                    },
                    "path_kind": "predicted",
                    "hmi": {"visual": "curve-warning-red-flashing", "audible": "warning-tone"},
                }
            ]
        }
    )

    vehicle_id: str = Field(description="the vehicle, as the query named it")
    state: SystemStateName = Field(
        description="the curve warning's system state (5.2-5.4; docs/service.md, its state diagram): off (switched "
        "off by the driver, 5.2), standby (on, not activated, 5.3), active (warnings given, 5.3.1), fault (no "
        "warning possible, 5.4: see fault_code)"
    )
    fault: str | None = Field(
        description="why the state is fault, for people (5.5.3); its wording may change: programs read fault_code"
    )
    fault_code: FaultCode | None = Field(
        description="why the state is fault, a stable code (docs/service.md): no_map, no_map_match (no lane near "
        "the fix), stale_input (older than the last fix, or age_s beyond 2 s), invalid_input; null otherwise"
    )
    level: Literal[0, 1, 2] = Field(
        description="the curve warning level (6.1, 6.2.1: level 2 first): 0 none, 1 first level, 2 second level"
    )
    target: Trigger | None = Field(description="the CPOI the level is for (the nearest of that level); null at 0")
    triggers: list[Trigger] = Field(description="every triggering CPOI, nearest first")
    matched: Matched | None = Field(description="the lane the query was placed on; null where nothing matched")
    path_kind: PathKindName | None = Field(
        description="how the path ahead was found: route (the query's route), predicted (the most likely "
        "continuation at each junction); null where the system did not look ahead (not active)"
    )
    hmi: Hmi = Field(description="how to present the most urgent warning of the answer (5.5.1)")
    confirmed: ConfirmedFix | None = Field(
        default=None,
        description="only for a fix matched on the map that continues its vehicle's sequence: the vehicle's last "
        "matched fix as this one confirms it",
    )
    fcw: FcwAnswer | None = Field(default=None, description="only when the query has objects or a forward_target")


class Answers(BaseModel):
    """The answers of a batch, in the order of its queries: an answer, or an error entry for a query that was not
    answered (``?atomic=true``: a 422 instead)."""

    answers: list[WarningAnswer | BatchItemError] = Field(
        description="one entry per query, in order: a WarningAnswer, or a BatchItemError (it has an error field)"
    )


class VehicleState(BaseModel):
    """What the service keeps of one vehicle."""

    vehicle_id: str
    switched_on: bool
    category: Category | None
    state: SystemStateName = Field(description="as in a WarningAnswer")
    fault: str | None = Field(description="as in a WarningAnswer")
    fault_code: FaultCode | None = Field(default=None, description="as in a WarningAnswer")
    activated: bool
    last_timestamp_s: float | None
    network: str | None = Field(description="the network of its last match")
    lane_id: str | None = Field(description="its last matched lane")
