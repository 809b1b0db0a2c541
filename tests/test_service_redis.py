"""The Redis state store in trouble and at work, on a real ``redis-server`` (tests/redis_server.py):
sessions expiring by their TTL, a Redis down, hung or killed (503 with Retry-After, never a 500;
nothing acknowledged lost), and a Redis that cannot be reached at start-up (one line, exit 2).

The fleets' isolation and the far-future timestamp are tested on Redis too: their tests run on
each store (the ``state`` fixture of conftest.py).
"""

from __future__ import annotations

import logging
import subprocess
import sys
import time

import httpx
import pytest
from fastapi.testclient import TestClient
from servers import SwitchWriter, Workers
from servers import free_port as _free_port

from csws.networks import networks_dir
from service.app import create_app
from service.settings import ServiceSettings
from service.store.redis import SESSION_PREFIX, SETTING_PREFIX

TRACK_NET = networks_dir() / "t7_left.net.xml"
FIX = {"vehicle_id": "truck", "category": "N", "speed_kmh": 80.0, "lane_id": "curve_0", "lane_pos_m": 85.0}
IDLE_S = 1.0


def test_sessions_expire_by_their_ttl_and_settings_stay(redis_server, redis_url) -> None:
    app = create_app(ServiceSettings(nets=[TRACK_NET], state=redis_url, session_idle_s=IDLE_S))
    with TestClient(app) as client, redis_server.client() as redis:
        client.put("/v1/vehicles/parked", json={"switched_on": False, "category": "M3"})
        assert client.post("/v1/warning", json={**FIX, "timestamp_s": 100.0}).json()["state"] == "active"
        assert 0 < redis.pttl(SESSION_PREFIX + "truck") <= IDLE_S * 1000 and redis.pttl(SETTING_PREFIX + "parked") == -1
        assert client.get("/readyz").json()["vehicle_sessions"] == 2
        time.sleep(IDLE_S + 0.3)
        assert client.get("/v1/vehicles/truck").status_code == 404
        parked = client.get("/v1/vehicles/parked").json()
        assert (parked["switched_on"], parked["category"], parked["lane_id"]) == (False, "M3", None)
        # A new session starts afresh: the old timestamp no longer makes an older fix stale.
        assert client.post("/v1/warning", json={**FIX, "timestamp_s": 50.0}).json()["state"] == "active"


def _store_requests(client: TestClient) -> list[httpx.Response]:
    """One request of each kind that reads or writes the state store."""
    return [
        client.post("/v1/warning", json=FIX),
        client.post("/v1/warnings", json={"queries": [FIX]}),
        client.put("/v1/vehicles/truck", json={"switched_on": False}),
        client.get("/v1/vehicles/truck"),
        client.get("/readyz"),
    ]


def test_a_redis_down_or_hung_is_503_with_retry_after_and_one_log_line(own_redis, caplog) -> None:
    app = create_app(ServiceSettings(nets=[TRACK_NET], state=own_redis.url()))
    with TestClient(app, raise_server_exceptions=False) as client:
        assert [r.status_code for r in _store_requests(client)] == [200] * 5
        for trouble, again in ((own_redis.pause, own_redis.resume), (own_redis.kill, own_redis.start)):
            trouble()
            caplog.clear()
            started = time.monotonic()
            with caplog.at_level(logging.WARNING, logger="csws.service"):
                answers = _store_requests(client)
            assert [r.status_code for r in answers] == [503] * 5 and time.monotonic() - started < 10.0
            assert all(r.headers["retry-after"] == "1" and "retry" in r.json()["detail"] for r in answers)
            assert len(caplog.records) == 5 and all(own_redis.url() in r.getMessage() for r in caplog.records)
            assert client.get("/healthz").status_code == 200
            again()
            assert [r.status_code for r in _store_requests(client)] == [200] * 5


@pytest.mark.slow
def test_a_redis_killed_during_puts_loses_no_acknowledged_one(own_redis) -> None:
    # Redis as docs/service.md asks: the append-only file, fsynced at every write.
    running = Workers([TRACK_NET], "--state", own_redis.url())
    try:
        writer = SwitchWriter(running.url)
        writer.wait_for(lambda w: len(w.acknowledged) >= 100)
        own_redis.kill()
        writer.wait_for(lambda w: len(w.refused) >= 20)
        own_redis.start()
        writer.assert_stored({"state": own_redis.url()})
    finally:
        running.stop()
    assert {(r.status_code, r.headers.get("retry-after")) for r in writer.refused} == {(503, "1")}
    assert len(writer.acknowledged) + len(writer.refused) == 1000


@pytest.mark.slow
@pytest.mark.parametrize("workers", ["1", "2"])
def test_an_unreachable_redis_stops_start_up_in_one_line_naming_it(workers) -> None:
    url = f"redis://:secret@127.0.0.1:{_free_port()}/0"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "csws",
            "serve",
            "--net",
            str(TRACK_NET),
            "--state",
            url,
            "--port",
            "0",
            "--workers",
            workers,
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2, result.stderr
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("csws: error: cannot reach the state store ")
    assert url.replace("secret", "***") in result.stderr and "secret" not in result.stderr


def test_a_state_that_is_no_redis_url_is_refused() -> None:
    with pytest.raises(ValueError, match="give a Redis URL"):
        ServiceSettings(nets=[TRACK_NET], state="postgres://127.0.0.1/0")
