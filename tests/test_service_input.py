"""The HTTP service refuses bad input with a clear 422: queries, batches, map requests and switches.

Served by a real uvicorn on loopback (``served_server`` of conftest.py: the geo-referenced Table 7
track and the side roads), so that every refusal passes the whole stack a client's request does.
"""

from __future__ import annotations

import json

import httpx
import pytest


@pytest.fixture
def client(served_server) -> httpx.Client:
    return served_server.client


GOOD = {"vehicle_id": "bad-input", "category": "N", "speed_kmh": 50.0, "position": {"x": 100.0, "y": 0.0}}


def _with(**changes) -> str:
    return json.dumps({**GOOD, **changes})


BAD_QUERIES = {
    "nan-speed": (_with(speed_kmh=0).replace('"speed_kmh": 0', '"speed_kmh": NaN'), "finite number"),
    "infinite-x": (_with(position={"x": 1, "y": 0}).replace('"x": 1', '"x": Infinity'), "finite number"),
    "negative-speed": (_with(speed_kmh=-1), "greater than or equal to 0"),
    "speed-above-250": (_with(speed_kmh=251), "less than or equal to 250"),
    "unknown-category": (_with(category="Q"), "Input should be 'M1', 'M2', 'M3', 'N' or 'O'"),
    "lon-out-of-range": (_with(position={"lon": 200.0, "lat": 50.0}), "less than or equal to 180"),
    "lat-out-of-range": (_with(position={"lon": 9.0, "lat": -95.0}), "greater than or equal to -90"),
    "heading-360": (_with(heading_deg=360.0), "less than 360"),
    "negative-heading": (_with(heading_deg=-0.5), "greater than or equal to 0"),
    "unknown-lane": (_with(lane_id="nowhere_0", lane_pos_m=1.0), "unknown lane id 'nowhere_0'"),
    "lane-pos-beyond": (_with(lane_id="approach_0", lane_pos_m=950.0), "beyond the end of lane 'approach_0'"),
    "lane-without-pos": (_with(lane_id="approach_0"), "lane_id and lane_pos_m go together"),
    "unknown-edge": (_with(route=["approach", "nowhere"]), "unknown edge id 'nowhere'"),
    "half-position": (_with(position={"x": 1.0}), "either x and y"),
    "no-position": (json.dumps({k: v for k, v in GOOD.items() if k != "position"}), "needs a position"),
    "empty-vehicle-id": (_with(vehicle_id=""), "at least 1 character"),
    "no-category": (
        json.dumps({**{k: v for k, v in GOOD.items() if k != "category"}, "vehicle_id": "anon"}),
        "category is required",
    ),
    "malformed-json": ('{"vehicle_id": "x", ', "JSON"),
    # A typo would otherwise pass as if the field were not given: named, with the field meant.
    "typo-heading": (_with(heading=90.0), "unknown field 'heading': did you mean 'heading_deg'?"),
    "typo-timestamp": (_with(timestamp=10.0), "unknown field 'timestamp': did you mean 'timestamp_s'?"),
    "unknown-in-position": (_with(position={"x": 1.0, "y": 0.0, "z": 3.0}), "unknown field 'z'"),
    "unknown-network": (_with(network="atlantis"), "unknown network 'atlantis': served are side_roads, t7_geo"),
    "lane-not-in-network": (
        _with(network="side_roads", lane_id="approach_0", lane_pos_m=1.0),
        "unknown lane id 'approach_0': not in network 'side_roads'",
    ),
    "edge-not-in-network": (
        _with(network="side_roads", route=["approach"]),
        "unknown edge id 'approach': not in network 'side_roads'",
    ),
}


@pytest.mark.parametrize("body, message", BAD_QUERIES.values(), ids=BAD_QUERIES.keys())
def test_bad_queries_get_a_clear_422(client, body: str, message: str) -> None:
    """Alone, and in an all-or-nothing batch, a 422; in a batch, an error entry at its index saying the same
    (a body that is not JSON stays a 422)."""
    batch = f'{{"queries": [{json.dumps(GOOD)}, {body}]}}'
    for path, payload in (("/v1/warning", body), ("/v1/warnings?atomic=true", batch)):
        response = client.post(path, content=payload, headers={"content-type": "application/json"})
        assert response.status_code == 422, response.text
        assert message in json.dumps(response.json()), response.text
        if path != "/v1/warning" and message != "JSON":
            assert response.json()["detail"][0]["loc"][:3] == ["body", "queries", 1]
    response = client.post("/v1/warnings", content=batch, headers={"content-type": "application/json"})
    if message == "JSON":
        assert response.status_code == 422, response.text
        return
    assert response.status_code == 200, response.text
    good, bad = response.json()["answers"]
    assert good["vehicle_id"] == GOOD["vehicle_id"] and "error" not in good
    assert bad["index"] == 1 and message in json.dumps(bad["error"]), bad
    assert all(problem["loc"][:3] == ["body", "queries", 1] for problem in bad["error"]["detail"])


def test_an_oversized_batch_is_refused(client) -> None:
    response = client.post("/v1/warnings", json={"queries": [GOOD] * 10_001})
    assert response.status_code == 422
    assert response.json()["detail"][0]["msg"] == "List should have at most 10000 items, not 10001"


@pytest.mark.parametrize(
    "path, params, message",
    [
        ("/v1/horizon", {"lane_id": "approach_0", "lane_pos_m": 1.0, "length_m": 0.0}, "greater than 0"),
        ("/v1/horizon", {"x": "nan", "y": 0.0}, "finite number"),
        ("/v1/horizon", {"lane_id": "nowhere_0", "lane_pos_m": 1.0}, "unknown lane id"),
        ("/v1/curves", {"bbox": "1,2,3"}, "four finite numbers"),
        ("/v1/curves", {"network": "atlantis"}, "unknown network"),
    ],
)
def test_bad_map_requests_get_a_clear_422(client, path, params, message) -> None:
    response = client.get(path, params=params)
    assert response.status_code == 422, response.text
    assert message in response.text


def test_a_bad_switch_gets_a_clear_422(client) -> None:
    response = client.put("/v1/vehicles/v", json={"switched_on": "maybe"})
    assert response.status_code == 422
    assert "valid boolean" in response.text
    response = client.put("/v1/vehicles/v", json={"switched_on": False, "categroy": "N"})
    assert response.status_code == 422
    assert "unknown field 'categroy': did you mean 'category'?" in response.text


def test_an_unknown_batch_field_is_named(client) -> None:
    """A batch whose list is misspelt is refused with the field meant, not answered empty; a long
    unknown name is cut, and one resembling nothing is named alone."""
    response = client.post("/v1/warnings", json={"query": [GOOD]})
    assert response.status_code == 422
    messages = [problem["msg"] for problem in response.json()["detail"]]
    assert "unknown field 'query': did you mean 'queries'?" in messages
    response = client.post("/v1/warning", json={**GOOD, "zzz" + "x" * 10_000: 1})
    assert response.status_code == 422
    assert len(response.text) < 1_000
    assert any(problem["msg"].startswith("unknown field 'zzzx") for problem in response.json()["detail"])
