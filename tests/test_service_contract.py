"""The answer contract an on-board unit codes against, asked of a real server on loopback: batches answered
per query, the enumerations and descriptions of the OpenAPI, stable fault codes, and speed 0 (T/ITS 0091-2018
5.3)."""

from __future__ import annotations

import time

import pytest
from builders import TRACK_NET
from fastapi.testclient import TestClient
from markers import marks_its_tests
from servers import Server

from csws.state import Fault, SystemState
from csws.warning.rules import HmiHint, PathKind
from service.app import create_app
from service.fcw import FCW_HMI_HINTS
from service.settings import ServiceSettings

ROUTE = ["approach", "curve", "runout"]
#: Where curve 1 (R 120 m) of the Table 7 track begins: curve_0 at 100 m (networks/t7_left.truth.json).
CURVE_1_START_POS_M = 100.0
#: Table 2 (level 2), R 120 m, column M3/N/O: V_w, km/h.
TABLE_2_VW_R120_N_KMH = 78.0
#: g of formula (1), m/s^2.
G_MPS2 = 9.81
#: The fault codes of the contract: stable, whatever the wording of ``fault``.
FAULT_CODES = {"no_map", "no_map_match", "stale_input", "invalid_input"}


def _warning_distance_m(speed_kmh: float, warning_speed_kmh: float) -> float:
    """S_w of formula (1) (6.1), m."""
    v, vw = speed_kmh / 3.6, warning_speed_kmh / 3.6
    return v * (0.8 + (v * v - vw * vw) / (v * G_MPS2))


def _query(vehicle_id: str, lane_pos_m: float = 500.0, speed_kmh: float = 80.0, **extra) -> dict:
    return {
        "vehicle_id": vehicle_id,
        "category": "N",
        "speed_kmh": speed_kmh,
        "lane_id": "approach_0",
        "lane_pos_m": lane_pos_m,
        "route": ROUTE,
        **extra,
    }


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def server(tmp_path_factory):
    running = Server([TRACK_NET], tmp_path_factory.mktemp("state") / "vehicles.sqlite3")
    yield running
    running.stop()


@pytest.fixture
def client(server):
    return server.client


def _without_id(answer: dict) -> dict:
    return {key: value for key, value in answer.items() if key != "vehicle_id"}


@pytest.mark.parametrize(
    "bad, code, field",
    [
        ({"speed_kmh": -5.0}, "invalid_query", "speed_kmh"),
        ({"speed_kmh": "80"}, "invalid_query", "speed_kmh"),
        ({"heading": 90.0}, "invalid_query", "heading"),
        ({"lane_id": "nowhere_0"}, "unanswerable_query", "lane_id"),
        ({"lane_pos_m": 1e6}, "unanswerable_query", "lane_pos_m"),
    ],
)
def test_a_bad_query_in_a_batch_gets_an_error_entry_and_leaves_its_session(client, bad, code, field):
    key = f"{code}-{field}"
    first = client.post("/v1/warning", json=_query(f"bad-{key}", timestamp_s=10.0))
    assert first.status_code == 200, first.text
    before = client.get(f"/v1/vehicles/bad-{key}").json()
    batch = [
        _query(f"a-{key}", 850.0, 90.0, timestamp_s=11.0),
        {**_query(f"bad-{key}", timestamp_s=20.0), **bad},
        _query(f"c-{key}", 300.0, 60.0, timestamp_s=11.0),
    ]
    response = client.post("/v1/warnings", json={"queries": batch})
    assert response.status_code == 200, response.text
    answers = response.json()["answers"]
    assert len(answers) == 3
    error = answers[1]
    assert (error["index"], error["vehicle_id"], error["error"]["code"]) == (1, f"bad-{key}", code)
    assert [problem["loc"][:4] for problem in error["error"]["detail"]] == [["body", "queries", 1, field]]
    assert field in error["error"]["message"]
    assert client.get(f"/v1/vehicles/bad-{key}").json() == before  # untouched: no timestamp 20 kept
    # The good ones are answered as they would be without the bad one (vehicles of their own).
    alone = client.post(
        "/v1/warnings",
        json={"queries": [{**batch[0], "vehicle_id": f"a2-{key}"}, {**batch[2], "vehicle_id": f"c2-{key}"}]},
    ).json()["answers"]
    assert [_without_id(answers[0]), _without_id(answers[2])] == [_without_id(answer) for answer in alone]
    assert answers[0]["vehicle_id"] == f"a-{key}" and answers[0]["state"] == "active"


def test_a_query_that_fails_alone_creates_no_session(client):
    response = client.post("/v1/warnings", json={"queries": [_query("fine"), _query("lost", lane_id="nowhere_0")]})
    assert response.status_code == 200
    assert response.json()["answers"][1]["error"]["code"] == "unanswerable_query"
    assert client.get("/v1/vehicles/lost").status_code == 404
    assert client.get("/v1/vehicles/fine").status_code == 200


def test_atomic_batches_are_all_or_nothing(client):
    batch = [_query("atomic-a"), _query("atomic-b", speed_kmh=-1.0), _query("atomic-c")]
    response = client.post("/v1/warnings", params={"atomic": "true"}, json={"queries": batch})
    assert response.status_code == 422
    assert response.json()["detail"][0]["loc"] == ["body", "queries", 1, "speed_kmh"]
    assert all(client.get(f"/v1/vehicles/atomic-{name}").status_code == 404 for name in "abc")
    good = client.post("/v1/warnings", params={"atomic": "true"}, json={"queries": [batch[0], batch[2]]})
    assert good.status_code == 200 and [a["state"] for a in good.json()["answers"]] == ["active", "active"]


@pytest.mark.parametrize(
    "body",
    ['{"queries": 5}', "[]", '{"queries": [], "extra": 1}', '{"queries": [', "{}", '{"queries": [1, 2]}'],
)
def test_a_body_that_is_no_batch_is_a_422(client, body):
    response = client.post("/v1/warnings", content=body, headers={"content-type": "application/json"})
    if body == '{"queries": [1, 2]}':  # a batch whose items are not queries: one entry each
        assert response.status_code == 200
        assert [entry["error"]["code"] for entry in response.json()["answers"]] == ["invalid_query"] * 2
        assert [entry["vehicle_id"] for entry in response.json()["answers"]] == [None, None]
    else:
        assert response.status_code == 422, response.text


def test_the_batch_counts_the_queries_it_did_not_answer(client):
    def refused() -> int:
        lines = client.get("/metrics").text.splitlines()
        prefix = 'csws_batch_item_errors_total{code="invalid_query"} '
        return next((int(line.removeprefix(prefix)) for line in lines if line.startswith(prefix)), 0)

    before = refused()
    client.post(
        "/v1/warnings", json={"queries": [_query("m1"), _query("m2", speed_kmh=-1.0), _query("m3", speed_kmh=999)]}
    )
    assert refused() == before + 2


# ------------------------------------------------------------------ the OpenAPI


def _schemas(client) -> dict:
    return client.get("/openapi.json").json()["components"]["schemas"]


def _enum(schema: dict) -> set:
    """The values of an enumeration, nullable or not."""
    options = schema.get("anyOf", [schema])
    return {value for option in options for value in option.get("enum", [])}


def test_the_answer_s_categorical_fields_are_enumerations(client):
    schemas = _schemas(client)
    answer = schemas["WarningAnswer"]["properties"]
    assert _enum(answer["state"]) == {state.value for state in SystemState}
    assert _enum(answer["level"]) == {0, 1, 2}
    assert _enum(answer["path_kind"]) == {kind.value for kind in PathKind}
    assert _enum(answer["fault_code"]) == {fault.code for fault in Fault} == FAULT_CODES
    hints = [HmiHint.for_level(level) for level in (0, 1, 2)] + list(FCW_HMI_HINTS.values())
    hmi = schemas["Hmi"]["properties"]
    assert _enum(hmi["visual"]) == {hint.visual for hint in hints} - {None}
    assert _enum(hmi["audible"]) == {hint.audible for hint in hints} - {None}
    assert _enum(schemas["FcwAnswer"]["properties"]["state"]) == {state.value for state in SystemState}
    assert _enum(schemas["ItemError"]["properties"]["code"]) == {"invalid_query", "unanswerable_query"}


@pytest.mark.parametrize(
    "model", ["WarningAnswer", "Trigger", "Matched", "Hmi", "FcwAnswer", "XY", "BatchItemError", "ItemError", "Problem"]
)
def test_every_field_of_the_answer_is_described(client, model):
    properties = _schemas(client)[model]["properties"]
    undescribed = [name for name, schema in properties.items() if not schema.get("description")]
    assert undescribed == []


def test_a_batch_s_answers_are_answers_or_error_entries_in_the_openapi(client):
    answers = _schemas(client)["Answers"]["properties"]["answers"]["items"]["anyOf"]
    assert {option["$ref"].rsplit("/", 1)[1] for option in answers} == {"WarningAnswer", "BatchItemError"}
    parameters = client.get("/openapi.json").json()["paths"]["/v1/warnings"]["post"]["parameters"]
    assert [(p["name"], p["in"], p["schema"]["default"]) for p in parameters] == [("atomic", "query", False)]


# ------------------------------------------------------------------ fault codes and speed 0


def test_each_fault_has_its_stable_code_beside_its_text(client):
    far = {"vehicle_id": "far", "category": "N", "speed_kmh": 50.0, "position": {"x": 5000.0, "y": 5000.0}}
    answer = client.post("/v1/warning", json=far).json()
    assert (answer["state"], answer["fault_code"]) == ("fault", "no_map_match")
    assert answer["fault"].startswith(Fault.NO_MAP_MATCH.value)
    stale = client.post("/v1/warning", json=_query("old", age_s=5.0)).json()
    assert (stale["state"], stale["fault_code"], stale["fault"]) == ("fault", "stale_input", Fault.STALE_INPUT.value)
    assert client.get("/v1/vehicles/old").json()["fault_code"] == "stale_input"
    good = client.post("/v1/warning", json=_query("fine-again")).json()
    assert (good["state"], good["fault"], good["fault_code"]) == ("active", None, None)


def test_speed_0_is_active_without_a_warning_as_activation_on_start_has_it(client):
    """5.3.2 a): the system activates with the vehicle's start, at any speed. At speed 0 it is active and warns
    of nothing (6.1: V >= V_w); at the same place at 100 km/h, 40 m before curve 1, it warns (formula (1))."""
    lane_pos_m = CURVE_1_START_POS_M - 40.0
    assert _warning_distance_m(100.0, TABLE_2_VW_R120_N_KMH) > 40.0
    standing = _query("standing", lane_pos_m, 0.0, lane_id="curve_0", timestamp_s=time.time())
    answer = client.post("/v1/warning", json=standing).json()
    assert (answer["state"], answer["level"], answer["fault_code"]) == ("active", 0, None)
    assert client.get("/v1/vehicles/standing").json()["activated"] is True
    moving = client.post("/v1/warning", json={**standing, "vehicle_id": "moving", "speed_kmh": 100.0}).json()
    assert (moving["state"], moving["level"]) == ("active", 2)


def test_speed_activation_is_a_service_setting_with_a_standing_vehicle_in_standby(monkeypatch):
    """5.3.2 b): CSWS_ACTIVATION_SPEED_KMH activates the system when the vehicle reaches that speed; a vehicle
    standing below it is in standby (5.3), one at it active."""
    monkeypatch.setenv("CSWS_ACTIVATION_SPEED_KMH", "15")
    settings = ServiceSettings(nets=[TRACK_NET], state_db=":memory:")
    assert settings.activation_speed_kmh == 15.0
    assert settings.engine_settings().activation.activation_speed_kmh == 15.0
    with TestClient(create_app(settings)) as client:
        standing = client.post("/v1/warning", json=_query("standing", speed_kmh=0.0)).json()
        assert (standing["state"], standing["level"]) == ("standby", 0)
        moving = client.post("/v1/warning", json=_query("moving", speed_kmh=15.0)).json()
        assert moving["state"] == "active"
    with pytest.raises(ValueError, match="activation_speed_kmh"):
        ServiceSettings(nets=[TRACK_NET], state_db=":memory:", activation_speed_kmh=-1.0)
