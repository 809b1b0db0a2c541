"""Fleets and API keys: a key sees and switches only its own fleet's vehicles; no key, no answer.

In-process (FastAPI's TestClient) for the contract of each route; the command line for
the key file and for the refusal to serve an open service beyond loopback.
"""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys

import pytest
from fastapi.testclient import TestClient

from csws.networks import networks_dir
from service.app import create_app
from service.keys import KEYS_FORMAT, KeyRing, Principal, Role, add_key
from service.security import MISSING_KEY, UNKNOWN_KEY, caller
from service.settings import ServiceSettings

TRACK_NET = networks_dir() / "t7_left.net.xml"


@pytest.fixture(scope="module")
def keys(tmp_path_factory) -> dict:
    path = tmp_path_factory.mktemp("keys") / "api-keys.json"
    made = {
        name: add_key(path, fleet, role)
        for name, fleet, role in (
            ("acme_admin", "acme", Role.ADMIN),
            ("acme_query", "acme", Role.QUERY),
            ("other_admin", "other", Role.ADMIN),
        )
    }
    return {"path": path, **made}


def _client(keys: dict, **settings) -> TestClient:
    return TestClient(
        create_app(
            ServiceSettings(nets=[TRACK_NET], api_keys_file=keys["path"], **{"state_db": ":memory:", **settings})
        )
    )


def _auth(key: str) -> dict:
    return {"Authorization": f"Bearer {key}"}


def _query(vehicle_id: str) -> dict:
    return {"vehicle_id": vehicle_id, "category": "N", "speed_kmh": 80.0, "lane_id": "curve_0", "lane_pos_m": 85.0}


def test_no_key_or_a_wrong_key_gets_401_with_a_challenge(keys) -> None:
    with _client(keys) as client:
        for headers in ({}, _auth("csws_not-a-key"), {"Authorization": f"Basic {keys['acme_admin']}"}):
            answer = client.post("/v1/warning", json=_query("truck"), headers=headers)
            assert answer.status_code == 401 and answer.headers["www-authenticate"].startswith("Bearer")
            wrong = headers.get("Authorization", "").startswith("Bearer")
            assert answer.json()["detail"] == (UNKNOWN_KEY if wrong else MISSING_KEY)
            assert ('error="invalid_token"' in answer.headers["www-authenticate"]) is wrong
            assert "acme" not in answer.text and "other" not in answer.text
            assert client.get("/v1/vehicles/truck", headers=headers).status_code == 401
            assert client.get("/v1/curves", headers=headers).status_code == 401
        assert client.get("/healthz").status_code == 200 and client.get("/readyz").status_code == 200
        assert client.get("/metrics").status_code == 401 and client.get("/openapi.json").status_code == 401
        assert client.get("/metrics", headers=_auth(keys["acme_query"])).status_code == 200


def test_docs_and_metrics_open_to_all_only_when_set(keys) -> None:
    with _client(keys, public_docs=True) as client:
        assert client.get("/openapi.json").status_code == 200 and client.get("/metrics").status_code == 200
        assert client.post("/v1/warning", json=_query("truck")).status_code == 401


def test_the_openapi_document_declares_the_key_scheme_on_the_keyed_routes(keys) -> None:
    with _client(keys) as client:
        schema = client.get("/openapi.json", headers=_auth(keys["acme_query"])).json()
    scheme = schema["components"]["securitySchemes"]["fleetKey"]
    assert (scheme["type"], scheme["scheme"]) == ("http", "bearer")
    keyed = [("/v1/warning", "post"), ("/v1/warnings", "post"), ("/v1/vehicles/{vehicle_id}", "put")]
    keyed += [("/v1/vehicles/{vehicle_id}", "get"), ("/v1/curves", "get"), ("/v1/horizon", "get")]
    keyed += [("/v1/roads", "get"), ("/v1/fleet", "get"), ("/metrics", "get")]
    for path, method in keyed:
        operation = schema["paths"][path][method]
        assert operation["security"] == [{"fleetKey": []}] and "401" in operation["responses"]
    assert "security" not in schema["paths"]["/healthz"]["get"] and "security" not in schema["paths"]["/readyz"]["get"]


def test_the_caller_dependency_can_be_overridden(keys) -> None:
    app = create_app(ServiceSettings(nets=[TRACK_NET], api_keys_file=keys["path"], state_db=":memory:"))

    async def acme_query_key() -> Principal:
        return Principal("acme", Role.QUERY)

    app.dependency_overrides[caller] = acme_query_key
    with TestClient(app) as client:
        assert client.post("/v1/warning", json=_query("truck")).json()["vehicle_id"] == "truck"  # no key needed
        assert client.put("/v1/vehicles/truck", json={"switched_on": False}).status_code == 403  # not an admin


def test_a_fleet_sees_and_switches_only_its_own_vehicles(keys, state) -> None:
    with _client(keys, **state) as client:
        switched = client.put("/v1/vehicles/truck", json={"switched_on": False}, headers=_auth(keys["acme_admin"]))
        assert switched.status_code == 200 and switched.json()["vehicle_id"] == "truck"
        # The other fleet's "truck" is another vehicle: unknown to it, and still warned.
        assert client.get("/v1/vehicles/truck", headers=_auth(keys["other_admin"])).status_code == 404
        theirs = client.post("/v1/warning", json=_query("truck"), headers=_auth(keys["other_admin"])).json()
        assert theirs["vehicle_id"] == "truck" and theirs["state"] == "active" and theirs["level"] == 2
        ours = client.post("/v1/warning", json=_query("truck"), headers=_auth(keys["acme_query"])).json()
        assert ours["vehicle_id"] == "truck" and ours["state"] == "off" and ours["level"] == 0
        batch = client.post(
            "/v1/warnings", json={"queries": [_query("truck"), _query("van")]}, headers=_auth(keys["acme_query"])
        ).json()["answers"]
        assert [(a["vehicle_id"], a["state"]) for a in batch] == [("truck", "off"), ("van", "active")]
        state = client.get("/v1/vehicles/truck", headers=_auth(keys["acme_query"])).json()
        assert state["vehicle_id"] == "truck" and state["switched_on"] is False


def test_only_an_admin_key_switches(keys) -> None:
    with _client(keys) as client:
        answer = client.put("/v1/vehicles/bus", json={"switched_on": False}, headers=_auth(keys["acme_query"]))
        assert answer.status_code == 403
        assert client.get("/v1/vehicles/bus", headers=_auth(keys["acme_admin"])).status_code == 404


def test_the_key_file_keeps_hashes_only_and_its_owner_alone_reads_it(keys) -> None:
    content = json.loads(keys["path"].read_text("utf-8"))
    assert content["format"] == KEYS_FORMAT and len(content["keys"]) == 3
    text = keys["path"].read_text("utf-8")
    assert all(keys[name] not in text for name in ("acme_admin", "acme_query", "other_admin"))
    assert stat.S_IMODE(os.stat(keys["path"]).st_mode) == 0o600
    ring = KeyRing(keys["path"])
    assert ring.principal(keys["acme_query"]).fleet == "acme" and ring.principal(keys["acme_query"]).role is Role.QUERY
    assert ring.principal(keys["acme_query"] + "x") is None


@pytest.mark.parametrize(
    "content",
    [
        "not json",
        json.dumps({"format": "other", "keys": []}),
        json.dumps({"format": KEYS_FORMAT, "keys": [{"fleet": "a/b", "role": "admin", "sha256": "0" * 64}]}),
    ],
)
def test_a_bad_key_file_stops_start_up_in_one_line_naming_it(tmp_path, content) -> None:
    path = tmp_path / "keys.json"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(ValueError, match=str(path)):
        create_app(ServiceSettings(nets=[TRACK_NET], state_db=":memory:", api_keys_file=path))


def _csws(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "csws", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, **(env or {})},
    )


def test_keys_add_prints_a_working_key_once(tmp_path) -> None:
    path = tmp_path / "keys.json"
    made = _csws("keys", "add", "acme", "--role", "admin", "--file", str(path))
    assert made.returncode == 0, made.stderr
    key = made.stdout.strip()
    assert KeyRing(path).principal(key).fleet == "acme" and "shown only this once" in made.stderr
    bad = _csws("keys", "add", "no/slash", "--file", str(path))
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "fleet must be" in bad.stderr


@pytest.mark.slow
def test_an_open_service_is_refused_beyond_loopback_in_one_line() -> None:
    refused = _csws("serve", "--host", "0.0.0.0", "--port", "1", "--net", str(TRACK_NET))
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1
    assert "refusing to serve without API keys on 0.0.0.0" in refused.stderr
    assert ServiceSettings(nets=[TRACK_NET], host="0.0.0.0", insecure=True).insecure
    assert ServiceSettings(nets=[TRACK_NET], host="::1").host == "::1"
