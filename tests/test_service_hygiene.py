"""The service on an open network, against a real ``csws serve`` on loopback: malformed bytes are
4xx, a busy port is an error, a vanished state database is noticed, slow clients are timed
out, settings are bounded by what the store holds, and pages carry security headers."""

from __future__ import annotations

import base64
import hashlib
import json
import logging
import os
import re
import resource
import socket
import sqlite3
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import pytest
from markers import marks_its_tests
from servers import free_port

from csws.networks import networks_dir
from service.run import served_url
from service.settings import ServiceSettings
from service.store import MAX_SESSION_IDLE_S, StoreUnavailable, VehicleSetting, VehicleWrite, checked_idle_s
from service.store.redis import RedisStore
from service.store.sqlite import SQLiteStore

TRACK_NET = networks_dir() / "t7_left.net.xml"
HEAD_TIMEOUT_S = 2.0
#: How much later than its deadline a slow connection may be closed, s (a loaded CI machine).
SLACK_S = 1.5
QUERY = {"vehicle_id": "truck", "category": "N", "speed_kmh": 80.0, "lane_id": "curve_0", "lane_pos_m": 85.0}
STARTUP_TIMEOUT_S = 60.0


class Serve:
    """``csws serve`` on the Table 7 track on a free loopback port, its output in a file."""

    def __init__(self, folder: Path, *options: str, nofile: int | None = None, **env: str) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.log = folder / f"serve-{self.port}.log"
        with self.log.open("wb") as log:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "csws", "serve", f"--net={TRACK_NET}", "--port", str(self.port), *options],
                stdout=log,
                stderr=subprocess.STDOUT,
                env={**os.environ, **{f"CSWS_{k.upper()}": v for k, v in env.items()}},
                start_new_session=True,
                preexec_fn=(lambda: resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))) if nofile else None,
            )
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        while time.monotonic() < deadline:
            assert self.process.poll() is None, self.output()
            try:
                if httpx.get(f"{self.url}/readyz", timeout=2.0).status_code == 200:
                    return
            except httpx.TransportError:
                time.sleep(0.1)
        self.stop()
        raise RuntimeError(f"csws serve was not ready within {STARTUP_TIMEOUT_S} s")

    def output(self) -> str:
        return self.log.read_text(errors="replace")

    def stop(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(self.process.pid, 9)
            self.process.wait(timeout=10)


def _csws_serve_fails(*options: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess:
    """``csws serve`` with ``options``, expected to end by itself."""
    return subprocess.run(
        [sys.executable, "-m", "csws", "serve", f"--net={TRACK_NET}", *options],
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def served(tmp_path_factory):
    running = Serve(
        tmp_path_factory.mktemp("served"),
        "--state-db",
        str(tmp_path_factory.mktemp("state") / "vehicles.sqlite3"),
        head_timeout_s=str(HEAD_TIMEOUT_S),
    )
    yield running
    running.stop()


# (a) Every malformed byte is a 4xx.

BAD_UTF8 = b"\xff\xfe\xc3("


def _bodies_with(raw_value: bytes) -> dict[tuple[str, str], bytes]:
    """Request bodies of each JSON route with ``raw_value`` (raw bytes) as a string value."""
    query = (
        b'{"vehicle_id": "' + raw_value + b'", "category": "N", "speed_kmh": 80.0, '
        b'"lane_id": "curve_0", "lane_pos_m": 85.0}'
    )
    return {
        ("POST", "/v1/warning"): query,
        ("POST", "/v1/warnings"): b'{"queries": [' + query + b"]}",
        ("PUT", "/v1/vehicles/truck"): b'{"switched_on": true, "category": "' + raw_value + b'"}',
    }


def _refusal(method: str, url: str, body: bytes) -> str:
    """What the service says of a bad body: its 422; for a batch, the error entry of its one query (a 422 with
    ``?atomic=true`` too)."""
    headers = {"content-type": "application/json"}
    if not url.endswith("/v1/warnings"):
        answer = httpx.request(method, url, content=body, headers=headers)
        assert answer.status_code == 422, (method, url, answer.text)
        return answer.text
    atomic = httpx.post(url + "?atomic=true", content=body, headers=headers)
    assert atomic.status_code == 422, atomic.text
    answer = httpx.post(url, content=body, headers=headers)
    assert answer.status_code == 200, answer.text
    [entry] = answer.json()["answers"]
    assert entry["error"]["code"] == "invalid_query"
    return json.dumps(entry) + atomic.text


def test_invalid_utf8_in_a_string_is_a_422_naming_it(served):
    for field_body in (_bodies_with(BAD_UTF8), {("POST", "/v1/warning"): b'{"route": ["' + BAD_UTF8 + b'"]}'}):
        for (method, path), body in field_body.items():
            refusal = _refusal(method, served.url + path, body)
            assert refusal.lower().count("unicode") >= (2 if path == "/v1/warnings" else 1), refusal


@pytest.mark.parametrize("depth", [1_000, 100_000])
def test_deep_nesting_in_an_unknown_field_is_a_422(served, depth):
    nested = b"[" * depth + b"]" * depth
    for (method, path), body in _bodies_with(b"truck").items():
        deep = body[:-1] + b', "extra": ' + nested + b"}"
        answer = httpx.request(method, served.url + path, content=deep, headers={"content-type": "application/json"})
        assert answer.status_code == 422, (method, path, answer.status_code, answer.text[:200])
        assert "recursion" in answer.text


@pytest.mark.parametrize("vehicle_id", ["a\x00b", "fleet/truck", "/", "\x00"])
def test_ids_with_nul_or_slash_are_refused_in_bodies_and_paths(served, vehicle_id):
    """One rule: no '/' and no U+0000 in a vehicle id, wherever it comes (the pattern is named)."""
    for path in ("/v1/warning", "/v1/warnings"):
        body = {**QUERY, "vehicle_id": vehicle_id}
        refusal = _refusal(
            "POST", served.url + path, json.dumps(body if path == "/v1/warning" else {"queries": [body]}).encode()
        )
        assert refusal.count("pattern") >= (2 if path == "/v1/warnings" else 1), refusal
    if "/" not in vehicle_id:  # a '/' leaves the path: no route names such a vehicle
        quoted = vehicle_id.replace("\x00", "%00")
        put = httpx.put(f"{served.url}/v1/vehicles/{quoted}", json={"switched_on": False})
        get = httpx.get(f"{served.url}/v1/vehicles/{quoted}")
        assert put.status_code == get.status_code == 422 and "pattern" in put.text, put.text
    fleet = httpx.get(f"{served.url}/v1/fleet").text
    assert vehicle_id not in fleet


def test_an_echoed_value_is_cut(served):
    from service.checks import SHOWN_CHARS

    edge_id = "e" * 1_000_000
    answer = httpx.post(f"{served.url}/v1/warning", json={**QUERY, "route": [edge_id]}, timeout=30.0)
    assert answer.status_code == 422
    assert len(answer.content) < 1000, len(answer.content)
    assert repr(edge_id[:SHOWN_CHARS]) + "..." in answer.json()["detail"][0]["msg"]


# (b) A busy port is an error.


@pytest.mark.parametrize("workers", [1, 2])
def test_a_busy_port_is_an_error_before_serving(served, tmp_path, workers):
    """Also when the service on the port is another csws serve (whose sockets have SO_REUSEPORT)."""
    second = _csws_serve_fails(
        "--port", str(served.port), "--workers", str(workers), "--state-db", str(tmp_path / "v.sqlite3")
    )
    assert second.returncode != 0
    assert "serving" not in second.stdout
    assert f"cannot listen on 127.0.0.1:{served.port}: it is in use" in second.stderr
    assert httpx.get(f"{served.url}/readyz").status_code == 200


def test_an_ipv6_address_is_printed_in_brackets():
    assert served_url("::1", 8000) == "http://[::1]:8000"
    assert served_url("127.0.0.1", 8000) == "http://127.0.0.1:8000"


# (c) The store is watched.


@pytest.mark.slow
def test_a_deleted_database_is_noticed_by_every_worker(tmp_path):
    """With two workers; whose port is busy for another csws serve, too."""
    database = tmp_path / "state" / "vehicles.sqlite3"
    two = Serve(tmp_path, "--workers", "2", "--state-db", str(database))
    try:
        second = _csws_serve_fails("--port", str(two.port), "--state-db", str(tmp_path / "w.sqlite3"))
        assert second.returncode != 0 and "serving" not in second.stdout
        assert "it is in use" in second.stderr
        with httpx.Client(base_url=two.url) as client:
            assert client.put("/v1/vehicles/v0", json={"switched_on": False}).status_code == 200
            database.unlink()
            answers = []
            for number in range(1, 41):  # new connections: the kernel spreads them over both workers
                with httpx.Client(base_url=two.url) as fresh:
                    answers.append(fresh.put(f"/v1/vehicles/v{number}", json={"switched_on": False}))
            assert {a.status_code for a in answers} == {503}, "a write to the deleted file was acknowledged"
            assert all(a.headers["retry-after"] for a in answers)
            assert "was deleted" in answers[0].json()["detail"]
            ready = [httpx.get(f"{two.url}/readyz").status_code for _ in range(10)]
            assert set(ready) == {503}
        assert not database.exists(), "a worker made a new, empty file"
    finally:
        two.stop()
    logged = [line for line in two.output().splitlines() if "was deleted" in line]
    assert 1 <= len(logged) <= 2 + 2, logged  # one per worker, and the rate-limited 503 warnings


def _store(path: Path) -> SQLiteStore:
    store = SQLiteStore(path, 600.0)
    store.check()
    return store


def _switch_off(store: SQLiteStore, vehicle_id: str) -> None:
    store.write({vehicle_id: VehicleWrite(0, b"session", VehicleSetting(switched_on=False))})


def test_a_replaced_or_read_only_database_refuses_writes(tmp_path):
    path = tmp_path / "vehicles.sqlite3"
    store = _store(path)
    _switch_off(store, "a")
    other = tmp_path / "other.sqlite3"
    sqlite3.connect(other).close()
    os.replace(other, path)
    with pytest.raises(StoreUnavailable, match="replaced"):
        _switch_off(store, "b")
    with pytest.raises(StoreUnavailable, match="replaced"):
        store.read(["a"])
    store.close()

    read_only = tmp_path / "read-only.sqlite3"
    store = _store(read_only)
    _switch_off(store, "a")
    read_only.chmod(0o400)
    with pytest.raises(StoreUnavailable, match="read-only"):
        _switch_off(store, "b")
    with pytest.raises(StoreUnavailable, match="read-only"):
        store.session_count()
    store.close()


def test_the_database_and_its_wal_are_private(tmp_path):
    path = tmp_path / "private" / "vehicles.sqlite3"
    store = _store(path)
    _switch_off(store, "a")
    for file in (path, Path(f"{path}-wal"), Path(f"{path}-shm")):
        assert stat.S_IMODE(file.stat().st_mode) == 0o600, file
    store.close()


def test_a_database_of_each_worker_is_refused_with_workers():
    refused = _csws_serve_fails("--state-db", "", "--workers", "2", "--port", str(free_port()))
    assert refused.returncode != 0 and "serving" not in refused.stdout
    assert "each worker's own" in refused.stderr and "Traceback" not in refused.stderr
    for state_db in ("", " ", ":memory:"):
        with pytest.raises(ValueError, match="each worker's own"):
            ServiceSettings(nets=[TRACK_NET], state_db=state_db, workers=2)
    assert ServiceSettings(nets=[TRACK_NET], state_db="", workers=1).state_db == ""


# (d) Slow clients are timed out.


def _closed_after_s(port: int, sends: list[bytes], pause_s: float) -> float:
    """Seconds until the server closes a connection that sends ``sends`` one every ``pause_s``."""
    started = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=30.0) as sock:
        sock.setblocking(False)
        pending = list(sends)
        while time.monotonic() - started < 30.0:
            if pending:
                try:
                    sock.send(pending.pop(0))
                except OSError:
                    break
            try:
                if sock.recv(65536) == b"":
                    break
            except BlockingIOError:
                pass
            except OSError:
                break
            time.sleep(pause_s)
    return time.monotonic() - started


def test_slow_clients_are_closed_at_the_head_deadline_while_healthz_answers(served):
    drips = [b"GET /healthz HTTP/1.1\r\n"] + [b"X-Drip-%d: 1\r\n" % n for n in range(100)]
    cases = {
        "nothing": ([], 0.1),
        "partial request line": ([b"GET /hea"], 0.1),
        "dripped headers": (drips, 0.5),
        "keep-alive then drip": ([b"GET /healthz HTTP/1.1\r\nHost: a\r\n\r\n", *drips], 0.5),
    }
    closed_s: dict[str, float] = {}
    threads = [
        threading.Thread(target=lambda n=name, c=case: closed_s.__setitem__(n, _closed_after_s(served.port, *c)))
        for name, case in cases.items()
    ]
    for thread in threads:
        thread.start()
    healthz_s = []
    while any(thread.is_alive() for thread in threads):
        started = time.monotonic()
        assert httpx.get(f"{served.url}/healthz", timeout=5.0).status_code == 200
        healthz_s.append(time.monotonic() - started)
        time.sleep(0.1)
    for thread in threads:
        thread.join()
    for name, seconds in closed_s.items():
        assert seconds <= HEAD_TIMEOUT_S + SLACK_S + (0.5 if "keep-alive" in name else 0.0), (name, seconds)
    assert closed_s["dripped headers"] >= HEAD_TIMEOUT_S - 0.1  # closed by the deadline, not by something else
    assert max(healthz_s) < 1.0, healthz_s


def test_the_head_is_bounded_in_lines_and_bytes(served):
    many = httpx.get(f"{served.url}/healthz", headers=[(f"x-h{n}", "1") for n in range(150)])
    assert many.status_code == 431
    with socket.create_connection(("127.0.0.1", served.port), timeout=10.0) as sock:
        sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: a\r\nX-Big: " + b"a" * 20_000 + b"\r\n\r\n")
        assert sock.recv(1024).startswith(b"HTTP/1.1 431")
    with socket.create_connection(("127.0.0.1", served.port), timeout=10.0) as sock:
        sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: a\r\nX-Big: " + b"a" * 20_000)  # never complete
        assert sock.recv(1024).startswith(b"HTTP/1.1 400")


@pytest.mark.slow
def test_at_the_descriptor_limit_connections_are_refused_quietly(tmp_path):
    """140 idle connections at a limit of 128 descriptors: the extra ones get a 503 at once, the
    log stays short, and the service answers again as soon as they leave."""
    limited = Serve(tmp_path, "--state-db", str(tmp_path / "v.sqlite3"), nofile=128, head_timeout_s="30")
    idle = []
    try:
        for _ in range(140):
            idle.append(socket.create_connection(("127.0.0.1", limited.port), timeout=5.0))
        time.sleep(1.0)
        at_limit = httpx.get(f"{limited.url}/healthz", timeout=5.0)
        assert at_limit.status_code == 503 and at_limit.headers["retry-after"] == "1"
        for sock in idle:
            sock.close()
        idle.clear()
        started = time.monotonic()
        while httpx.get(f"{limited.url}/healthz", timeout=5.0).status_code != 200:
            assert time.monotonic() - started < 2.0
            time.sleep(0.05)
    finally:
        for sock in idle:
            sock.close()
        limited.stop()
    lines = limited.output().splitlines()
    assert len(lines) <= 10, "\n".join(lines)


# (e) Settings within what the store holds.


def test_a_session_idle_time_no_store_holds_is_one_error_line():
    refused = _csws_serve_fails(
        "--state", "redis://127.0.0.1:1/0", "--session-idle-s", "1e308", "--port", str(free_port())
    )
    assert refused.returncode == 2 and "serving" not in refused.stdout
    assert refused.stderr.strip().count("\n") == 0 and "Traceback" not in refused.stderr, refused.stderr
    assert "session idle time must be positive and at most" in refused.stderr


def test_the_longest_session_idle_time_is_taken_and_no_longer(tmp_path):
    """Both stores take the longest and refuse anything longer (1e17 s would start, then 503 on Redis)."""
    assert checked_idle_s(MAX_SESSION_IDLE_S) == MAX_SESSION_IDLE_S
    for idle_s in (0.0, -1.0, float("nan"), float("inf"), MAX_SESSION_IDLE_S * (1 + 1e-12), 1e17, 1e308):
        with pytest.raises(ValueError, match="at most"):
            RedisStore("redis://127.0.0.1:1/0", idle_s)
        with pytest.raises(ValueError, match="at most"):
            SQLiteStore(":memory:", idle_s)


def test_redis_holds_the_longest_session_idle_time(redis_url):
    store = RedisStore(redis_url, MAX_SESSION_IDLE_S)
    store.write({"hygiene/longest": VehicleWrite(0, b"session", VehicleSetting(switched_on=False))})
    stored = store.read(["hygiene/longest"])["hygiene/longest"]
    assert stored.session == b"session" and stored.setting == VehicleSetting(switched_on=False)
    store.close()


# (f) Security headers.


def _inline_script_hashes(page: bytes) -> set[str]:
    scripts = re.findall(rb"<script(?![^>]*\ssrc=)[^>]*>(.*?)</script>", page, re.DOTALL)
    return {"'sha256-" + base64.b64encode(hashlib.sha256(script).digest()).decode() + "'" for script in scripts}


@pytest.mark.parametrize("path", ["/map", "/docs", "/redoc", "/docs/oauth2-redirect"])
def test_pages_carry_a_content_security_policy_fitting_their_scripts(served, path):
    answer = httpx.get(served.url + path)
    assert answer.status_code == 200
    policy = dict(
        part.strip().split(" ", 1) for part in answer.headers["content-security-policy"].split(";") if part.strip()
    )
    assert policy["default-src"] == "'none'" and policy["frame-ancestors"] == "'none'"
    allowed = set(policy["script-src"].split())
    assert "'unsafe-inline'" not in allowed and "'unsafe-eval'" not in allowed
    assert _inline_script_hashes(answer.content) <= allowed
    for src in re.findall(rb'<script[^>]*\ssrc="([^"]+)"', answer.content):
        assert src.startswith(b"/"), src  # the service's own files ('self')
    assert answer.headers["x-content-type-options"] == "nosniff"
    assert answer.headers["x-frame-options"] == "DENY"


@pytest.mark.parametrize("path", ["/static/map.js", "/static/leaflet/leaflet.css", "/healthz", "/openapi.json"])
def test_other_answers_are_not_sniffed_or_framed(served, path):
    answer = httpx.get(served.url + path, headers={"accept-encoding": "gzip"})
    assert answer.status_code == 200
    assert answer.headers["x-content-type-options"] == "nosniff"
    assert answer.headers["x-frame-options"] == "DENY"


def test_a_flood_of_one_log_line_is_written_once_per_interval():
    from service.guard import OncePerInterval, OneLine

    interval_s = 0.2
    flood_filter = OncePerInterval(interval_s)

    def record(message: str, exc: BaseException | None = None) -> logging.LogRecord:
        return logging.LogRecord(
            "asyncio", logging.ERROR, __file__, 1, message, None, (type(exc), exc, None) if exc else None
        )

    written = [r for r in (record("accept() out of resources") for _ in range(1000)) if flood_filter.filter(r)]
    assert len(written) == 1
    time.sleep(interval_s * 1.5)
    later = record("accept() out of resources")
    assert flood_filter.filter(later) and "(and 999 more like it" in later.getMessage()
    assert flood_filter.filter(record("another line"))  # each message has its own interval

    emfile = record("socket.accept() out of system resource\nsocket: <fd=7>", OSError(24, "Too many open files"))
    assert OneLine().filter(emfile) and emfile.exc_info is None
    assert emfile.getMessage() == "socket.accept() out of system resource: [Errno 24] Too many open files"
