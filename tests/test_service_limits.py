"""Bounded requests against a real uvicorn on loopback: body limit, content type, stalled clients,
strict numbers, bounded metrics."""

from __future__ import annotations

import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from markers import marks_its_tests
from servers import Server, Workers

from csws.networks import networks_dir

TRACK_NET = networks_dir() / "t7_left.net.xml"
LIMIT_BYTES = 1_000_000
TIMEOUT_S = 1.0
QUERY = {"vehicle_id": "truck", "category": "N", "speed_kmh": 80.0, "lane_id": "curve_0", "lane_pos_m": 85.0}


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def server(tmp_path_factory):
    running = Server(
        [TRACK_NET],
        tmp_path_factory.mktemp("state") / "vehicles.sqlite3",
        max_body_bytes=str(LIMIT_BYTES),
        body_timeout_s=str(TIMEOUT_S),
    )
    yield running
    running.stop()


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise AssertionError("no VmRSS")


def _raw(port: int, head: bytes, body: bytes = b"", wait_s: float = 10.0) -> bytes:
    """Send a request by hand and read until the server closes or ``wait_s`` passes."""
    with socket.create_connection(("127.0.0.1", port), timeout=wait_s) as sock:
        sock.sendall(head + body)
        received = b""
        try:
            while chunk := sock.recv(65536):
                received += chunk
        except (TimeoutError, ConnectionResetError):
            pass
    return received


def test_a_declared_body_over_the_limit_is_413_before_it_is_read(server) -> None:
    before = _rss_mb(server.process.pid)
    head = (
        b"POST /v1/warnings HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 52428800\r\n\r\n"
    )
    started = time.monotonic()
    answer = _raw(server.port, head, b'{"queries": [')
    assert answer.startswith(b"HTTP/1.1 413") and time.monotonic() - started < 5.0
    assert _rss_mb(server.process.pid) - before < 50.0


def test_a_body_that_grows_past_the_limit_is_413(server) -> None:
    body = json.dumps({"queries": [QUERY] * 20_000}).encode()
    assert len(body) > LIMIT_BYTES
    answer = server.client.post(
        "/v1/warnings",
        content=iter([body[i : i + 65536] for i in range(0, len(body), 65536)]),
        headers={"Content-Type": "application/json"},
    )
    assert answer.status_code == 413


def test_a_body_not_declared_json_is_415(server) -> None:
    for headers in ({"Content-Type": "text/plain"}, {}):
        answer = server.client.post("/v1/warning", content=json.dumps(QUERY), headers=headers)
        assert answer.status_code == 415 and "application/json" in answer.json()["detail"]
    assert server.client.post("/v1/warning", json=QUERY).status_code == 200


def test_clients_that_stall_in_their_body_are_answered_and_closed_within_the_timeout(server) -> None:
    head = b"POST /v1/warning HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 100000\r\n\r\n"
    sockets = []
    for _ in range(50):
        sock = socket.create_connection(("127.0.0.1", server.port), timeout=10.0)
        sock.sendall(head + b'{"vehicle_id": ')  # and nothing more
        sockets.append(sock)
    started = time.monotonic()
    answers = []
    for sock in sockets:
        received = b""
        while chunk := sock.recv(65536):
            received += chunk
        answers.append(received)
        sock.close()
    assert all(answer.startswith(b"HTTP/1.1 408") for answer in answers)
    assert time.monotonic() - started < TIMEOUT_S + 5.0
    assert server.client.get("/healthz").status_code == 200


def test_a_request_without_a_key_is_401_before_its_body_is_read(tmp_path) -> None:
    from service.keys import Role, add_key

    keys_file = tmp_path / "api-keys.json"
    add_key(keys_file, "acme", Role.QUERY)
    keyed = Server([TRACK_NET], tmp_path / "vehicles.sqlite3", api_keys_file=str(keys_file), body_timeout_s="30")
    try:
        head = (
            b"POST /v1/warning HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 100000\r\n\r\n"
        )
        started = time.monotonic()
        with socket.create_connection(("127.0.0.1", keyed.port), timeout=10.0) as sock:
            sock.sendall(head + b'{"vehicle_id": ')  # and nothing more: the body is never complete
            answer = sock.recv(65536)
        assert answer.startswith(b"HTTP/1.1 401") and time.monotonic() - started < 5.0
    finally:
        keyed.stop()


@pytest.mark.parametrize("field, value", [("speed_kmh", "80"), ("speed_kmh", True), ("lane_pos_m", "85")])
def test_numbers_must_be_json_numbers(server, field, value) -> None:
    answer = server.client.post("/v1/warning", json={**QUERY, field: value})
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["body", field]


def test_a_switch_must_be_a_json_boolean(server) -> None:
    assert server.client.put("/v1/vehicles/bus", json={"switched_on": "false"}).status_code == 422
    assert server.client.put("/v1/vehicles/bus", json={"switched_on": False}).status_code == 200


def test_any_method_name_adds_no_metrics_series(server) -> None:
    for number in range(40):
        server.client.request(f"M{number}", "/healthz")
    metrics = server.client.get("/metrics").text
    assert not any(f'method="M{number}"' in metrics for number in range(40))
    assert 'method="other"' in metrics


# ------------------------------------------------------------------ the state database in trouble
def test_a_locked_state_database_is_a_503_to_retry_and_the_service_stays_up(tmp_path) -> None:
    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.settings import ServiceSettings

    state_db = tmp_path / "vehicles.sqlite3"
    with TestClient(create_app(ServiceSettings(nets=[TRACK_NET], state_db=str(state_db)))) as client:
        holder = sqlite3.connect(state_db, isolation_level=None)
        holder.execute("BEGIN EXCLUSIVE")  # another process holds the database
        started = time.monotonic()
        answer = client.put("/v1/vehicles/bus", json={"switched_on": False})
        assert answer.status_code == 503 and answer.headers["retry-after"] == "1"
        assert "cannot be written now" in answer.json()["detail"] and time.monotonic() - started < 3.0
        assert client.post("/v1/warning", json=QUERY).status_code == 503  # its session cannot be written either
        assert client.get("/healthz").status_code == 200
        holder.execute("ROLLBACK")
        holder.close()
        assert client.put("/v1/vehicles/bus", json={"switched_on": False}).status_code == 200


@pytest.mark.slow
@pytest.mark.parametrize("workers", ["1", "2"])
@pytest.mark.parametrize("content", ["corrupt", "foreign", "bad category"])
def test_a_bad_state_database_stops_start_up_in_one_line_naming_it(tmp_path, content, workers) -> None:
    state_db = tmp_path / "vehicles.sqlite3"
    if content == "corrupt":
        state_db.write_bytes(b"not a database " * 100)
    else:
        db = sqlite3.connect(state_db)
        if content == "foreign":
            db.execute("CREATE TABLE vehicle_settings (name TEXT)")
        else:
            db.execute(
                "CREATE TABLE vehicle_settings (vehicle_id TEXT PRIMARY KEY, switched_on INTEGER, category TEXT)"
            )
            db.execute("INSERT INTO vehicle_settings VALUES ('bus', 1, 'Q')")
        db.commit()
        db.close()
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "csws",
            "serve",
            "--net",
            str(TRACK_NET),
            "--state-db",
            str(state_db),
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
    assert (
        result.stderr.count("\n") == 1 and result.stderr.startswith("csws: error: ") and str(state_db) in result.stderr
    )


# ------------------------------------------------------------------ the master killed
def _children(pid: int) -> list[int]:
    """Processes whose parent is ``pid``."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


@pytest.mark.slow
def test_killing_the_master_leaves_no_worker_behind(tmp_path) -> None:
    running = Workers([TRACK_NET], "--state-db", str(tmp_path / "vehicles.sqlite3"))
    master = running.process
    try:
        workers = _children(master.pid)
        assert len(workers) >= 2
        master.send_signal(signal.SIGKILL)
        master.wait(timeout=10)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and any(Path(f"/proc/{pid}").exists() for pid in workers):
            time.sleep(0.2)
        assert not [pid for pid in workers if Path(f"/proc/{pid}").exists()]
    finally:
        for pid in _children(master.pid) if master.poll() is None else []:
            os.kill(pid, signal.SIGKILL)
        master.kill()


# ------------------------------------------------------------------ keep-alive through several workers
@pytest.mark.slow
def test_keep_alive_requests_through_several_workers_wait_for_no_acknowledgement(tmp_path) -> None:
    # Without TCP_NODELAY on the workers' connections, each answer after the first waits for the
    # client's delayed acknowledgement: about 40 ms on Linux.
    running = Workers([TRACK_NET], "--state-db", str(tmp_path / "vehicles.sqlite3"))
    try:
        with httpx.Client(base_url=running.url) as client:
            latencies_s = []
            for _ in range(21):
                started = time.perf_counter()
                client.get("/healthz").raise_for_status()
                latencies_s.append(time.perf_counter() - started)
        assert sorted(latencies_s)[10] < 0.02
    finally:
        running.stop()
