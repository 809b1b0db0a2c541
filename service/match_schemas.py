"""The contract of ``POST /v1/match``: a whole trace of fixes in, the matched lane of each fix out.

As OSRM's ``match`` and Valhalla's ``trace_attributes`` take a GPS trace and answer the road of
each point, the service takes a vehicle's fixes (x/y or lon/lat, time, and where known heading,
speed and accuracy) and answers for each the lane, edge and lane position the whole trace makes
most probable (:meth:`csws.road.hmm.SequenceMatcher.match_trace`). Bodies are validated strictly
as the warning queries are (:mod:`service.schemas`): a bad fix gets a 422 naming it and its field.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from .answer_schemas import XY
from .schemas import MAX_SPEED_KMH, Position

__all__ = ["MAX_TRACE", "TraceFix", "Trace", "MatchedFix", "MatchAnswer"]

#: Most fixes one trace may hold: an hour at 1 Hz, with room.
MAX_TRACE = 10_000


class TraceFix(BaseModel):
    """One fix of the trace."""

    model_config = ConfigDict(allow_inf_nan=False, extra="forbid")

    position: Position = Field(description="the fix")
    timestamp_s: float = Field(strict=True, description="when it was taken, s (any epoch; not before the previous fix)")
    heading_deg: float | None = Field(
        default=None, ge=0.0, lt=360.0, strict=True, description="GNSS heading, degrees clockwise from north"
    )
    speed_kmh: float | None = Field(default=None, ge=0.0, le=MAX_SPEED_KMH, strict=True, description="speed, km/h")
    accuracy_m: float | None = Field(
        default=None, gt=0.0, le=1000.0, strict=True, description="one standard deviation of the position, m"
    )


class Trace(BaseModel):
    """A vehicle's fixes in time order, matched as one sequence."""

    model_config = ConfigDict(
        allow_inf_nan=False,
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "fixes": [
                        {"position": {"x": 880.0, "y": 1.5}, "timestamp_s": 0.0, "heading_deg": 90.0},
                        {"position": {"x": 902.0, "y": -0.8}, "timestamp_s": 1.0, "heading_deg": 91.0},
                    ]
                }
            ]
        },
    )

    fixes: list[TraceFix] = Field(min_length=1, max_length=MAX_TRACE, description=f"1 to {MAX_TRACE} fixes")
    network: str | None = Field(
        default=None,
        min_length=1,
        max_length=256,
        description="the served network to match on; by default the best match over all of them",
    )

    @field_validator("fixes")
    @classmethod
    def _in_time_order(cls, fixes: list[TraceFix]) -> list[TraceFix]:
        """A trace's fixes never go back in time: a sequence is matched in the order it was driven."""
        for index in range(1, len(fixes)):
            if fixes[index].timestamp_s < fixes[index - 1].timestamp_s:
                raise ValueError(f"fixes must be in time order: fix {index} is before fix {index - 1}")
        return fixes


class MatchedFix(BaseModel):
    """Where one fix of the trace was matched."""

    network: str | None = Field(description="the network of the lane, null where the fix matched nothing")
    lane_id: str | None
    edge_id: str | None
    lane_pos_m: float | None = Field(description="lane position of the matched point, m")
    distance_m: float | None = Field(description="distance from the fix to the matched point, m")
    point: XY | None = Field(description="the matched point on the lane")
    placed: Literal["matched", "dead_reckoned"] | None = Field(
        description="matched on its lane, or dead-reckoned along the road from the last match (it matched no lane)"
    )
    reason: str | None = Field(description="why the fix matched nothing, else null")


class MatchAnswer(BaseModel):
    """The matched lane of each fix of the trace, in order."""

    matched: list[MatchedFix]
