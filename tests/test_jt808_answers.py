"""The gateway's answers without documents (``WarningService.answer(documents=False)``) say what the HTTP answers say.

Vehicles of two fleets drive the constructed road of the gateway tests (a straight, an arc of R 150 m) side by side
at the same speeds, one fleet answered as the HTTP service answers (every answer a document of the contract), the
other as the gateway does (the columns alone). Each report's state, level, target V_w and placement must be those of
the document, the V_w that of the standard's table for the constructed radius, and the events and sessions the two
fleets leave in the store the same.
"""

from __future__ import annotations

import math
from pathlib import Path

import msgspec
import pytest
from jt808_rig import APPROACH_M, CATEGORY, RADIUS_M, T0_S, build_net, lonlat

from csws.standard import warning_speed
from service.app import create_app
from service.decoding import DecodedPosition, DecodedQuery
from service.keys import vehicle_key
from service.settings import ServiceSettings

pytestmark = [pytest.mark.sumo]

#: The vehicles' speeds, km/h: below the curve's level-1 V_w, between the two, above both.
SPEEDS_KMH = (60.0, 80.0, 95.0, 110.0)


def _queries(step: int) -> list[DecodedQuery]:
    """The reports of the vehicles at ``step`` s, each from 700 m before the curve at its own speed."""
    queries = []
    for number, speed_kmh in enumerate(SPEEDS_KMH):
        lon, lat = lonlat(APPROACH_M - 700.0 + speed_kmh / 3.6 * step)
        queries.append(
            DecodedQuery(
                vehicle_id=f"v{number}",
                category=CATEGORY,
                speed_kmh=speed_kmh,
                position=DecodedPosition(lon=lon, lat=lat),
                heading_deg=90.0,
                timestamp_s=T0_S + step,
            )
        )
    return queries


def _vehicle_seq(event: dict) -> tuple[str, int]:
    return event["vehicle_id"], event["seq"]


def test_answers_without_documents_say_what_the_documents_say(tmp_path: Path) -> None:
    net = build_net(tmp_path)
    app = create_app(ServiceSettings(nets=[net], state_db=str(tmp_path / "vehicles.sqlite3")))
    service, store = app.state.service, app.state.store
    levels: set[int] = set()
    try:
        for step in range(34):  # all but the slowest pass the curve start, the fastest stays on the road
            full = service.answer(_queries(step), fleet="full")
            lean = service.answer(_queries(step), fleet="lean", documents=False)
            for row, document in enumerate(full.documents):
                assert (
                    (lean.state[row], lean.level[row])
                    == (full.state[row], full.level[row])
                    == (
                        document.state,
                        document.level,
                    )
                )
                target = document.target or {}
                assert lean.warning_speed_kmh[row] == full.warning_speed_kmh[row] == target.get("warning_speed_kmh")
                if lean.level[row]:
                    expected_kmh = warning_speed(RADIUS_M, CATEGORY, int(lean.level[row]))
                    assert math.isclose(lean.warning_speed_kmh[row], expected_kmh, rel_tol=0.03)
                placement, matched = lean.placement[row], document.matched
                assert placement is not None and matched is not None
                assert (placement.lane_id, placement.lane_pos_m) == (matched.lane_id, matched.lane_pos_m)
                assert service.networks[placement.network_index].name == matched.network
                levels.add(int(lean.level[row]))
        assert levels == {0, 1, 2}  # every level was answered both ways
        # Each vehicle's events in their order (one write's vehicles come in no set order).
        full_events, lean_events = (
            sorted((msgspec.json.decode(e.body) for e in store.events_after(fleet, None, 1000)), key=_vehicle_seq)
            for fleet in ("full", "lean")
        )
        assert full_events and [{**e, "fleet": "lean"} for e in full_events] == lean_events
        keys = [f"v{number}" for number in range(len(SPEEDS_KMH))]
        full_read = store.read([vehicle_key("full", key) for key in keys])
        lean_read = store.read([vehicle_key("lean", key) for key in keys])
        registry = service.registry
        for key in keys:
            full_record = registry.decode(full_read[vehicle_key("full", key)].session)
            lean_record = registry.decode(lean_read[vehicle_key("lean", key)].session)
            assert full_record is not None and lean_record is not None
            unanswered = {"latest": msgspec.structs.replace(full_record.latest, answered_at_s=None)}
            lean_unanswered = {"latest": msgspec.structs.replace(lean_record.latest, answered_at_s=None)}
            assert msgspec.structs.replace(full_record, **unanswered) == msgspec.structs.replace(
                lean_record, **lean_unanswered
            )
    finally:
        app.state.work.close()
        store.close()
