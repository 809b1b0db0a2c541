"""Operating ``csws serve``: its start-up lines, ``--log-level``, the JSON access log, ``/metrics`` summed over the
workers, and the ``compose.yaml`` that starts it with Redis."""

from __future__ import annotations

import json
import logging
import os
import shlex
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

import httpx
import pytest
import yaml
from builders import TRACK_NET
from markers import marks_its_tests
from servers import STARTUP_TIMEOUT_S, Workers, free_port

from csws.cli import build_parser
from service.access_log import ACCESS_LOGGER, AccessLog
from service.keys import add_key
from service.metrics import SHARE_PERIOD_S, Metrics
from service.run import settings_from_args

ROOT = Path(__file__).resolve().parents[1]
QUERY = {"vehicle_id": "t", "category": "N", "speed_kmh": 80.0, "lane_id": "approach_0", "lane_pos_m": 100.0}


def _counter(text: str, line_prefix: str) -> int:
    """The value of the metric line starting with ``line_prefix`` (0 where there is none)."""
    return next((int(float(line.rsplit(" ", 1)[1])) for line in text.splitlines() if line.startswith(line_prefix)), 0)


@pytest.fixture
@marks_its_tests("slow")
def workers(tmp_path):
    running = Workers([TRACK_NET], "--state-db", str(tmp_path / "vehicles.sqlite3"), workers=2)
    yield running
    running.stop()


def test_metrics_count_the_requests_of_every_worker(workers):
    first, second = workers.clients()
    for index in range(3):
        first.post("/v1/warning", json={**QUERY, "vehicle_id": f"first-{index}"}).raise_for_status()
    for index in range(5):
        second.post("/v1/warning", json={**QUERY, "vehicle_id": f"second-{index}"}).raise_for_status()
    posts = 'csws_http_requests_total{method="POST",route="/v1/warning",status="200"} '
    deadline = time.monotonic() + 10 * SHARE_PERIOD_S
    while True:
        seen = [first.get("/metrics").text, second.get("/metrics").text]
        if all(_counter(text, posts) == 8 for text in seen) or time.monotonic() > deadline:
            break
        time.sleep(SHARE_PERIOD_S / 4)
    assert [_counter(text, posts) for text in seen] == [8, 8]
    assert [_counter(text, "csws_worker_processes ") for text in seen] == [2, 2]
    assert _counter(seen[0], 'csws_answers_total{state="active",level="0"} ') == 8


def test_sharing_adds_up_every_counter():
    one, other = Metrics(), Metrics()
    for metrics, seconds in ((one, 0.003), (other, 0.3), (other, 20.0)):
        metrics.observe_request("POST", "/v1/warnings", 200, seconds)
    one.observe_answers(["active", "fault"], [2, 0])
    other.observe_item_errors(["invalid_query", "invalid_query", "unanswerable_query"])
    total = Metrics()
    total.add(json.loads(json.dumps(one.snapshot())))
    total.add(json.loads(json.dumps(other.snapshot())))
    text = total.lines(2)
    assert _counter(text, 'csws_http_requests_total{method="POST",route="/v1/warnings",status="200"} ') == 3
    assert _counter(text, 'csws_http_request_duration_seconds_bucket{route="/v1/warnings",le="0.005"} ') == 1
    assert _counter(text, 'csws_http_request_duration_seconds_bucket{route="/v1/warnings",le="0.5"} ') == 2
    assert _counter(text, 'csws_http_request_duration_seconds_bucket{route="/v1/warnings",le="+Inf"} ') == 3
    assert float(next(line for line in text.splitlines() if "_sum" in line).rsplit(" ", 1)[1]) == pytest.approx(20.303)
    assert _counter(text, 'csws_answers_total{state="active",level="2"} ') == 1
    assert _counter(text, 'csws_batch_item_errors_total{code="invalid_query"} ') == 2


def _serve(tmp_path: Path, *options: str) -> tuple[subprocess.Popen, str, Path, Path]:
    """``csws serve`` on a free loopback port with ``options``, ready; its standard output and error go to files."""
    url = f"http://127.0.0.1:{free_port()}"
    stdout, stderr = tmp_path / "stdout.log", tmp_path / "stderr.log"
    process = subprocess.Popen(
        [sys.executable, "-m", "csws", "serve", "--net", str(TRACK_NET), "--port", url.rsplit(":", 1)[1], *options],
        stdout=stdout.open("wb"),
        stderr=stderr.open("wb"),
        cwd=tmp_path,
    )
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"{url}/readyz", timeout=2.0).status_code == 200:
                return process, url, stdout, stderr
        except httpx.TransportError:
            time.sleep(0.2)
    process.kill()
    raise RuntimeError(f"csws serve was not ready: {stderr.read_text()}")


@pytest.mark.slow
def test_the_json_access_log_has_a_line_per_request_with_the_fleet_and_never_the_key(tmp_path):
    keys = tmp_path / "keys.json"
    key = add_key(keys, "acme", "query")
    process, url, stdout, stderr = _serve(
        tmp_path, "--api-keys", str(keys), "--state-db", str(tmp_path / "v.db"), "--access-log", "json",
        "--log-level", "info",
    )  # fmt: skip
    try:
        headers = {"authorization": f"Bearer {key}"}
        httpx.post(f"{url}/v1/warnings?atomic=false", json={"queries": [QUERY]}, headers=headers).raise_for_status()
        assert httpx.post(f"{url}/v1/warning", json=QUERY).status_code == 401
    finally:
        process.terminate()
        process.wait(timeout=15)
    text = stderr.read_text()
    assert key not in text
    lines = [json.loads(line) for line in text.splitlines() if line.startswith("{")]
    by_path = {(line["method"], line["path"]): line for line in lines}
    batch = by_path[("POST", "/v1/warnings")]
    assert list(batch) == ["time", "method", "path", "status", "duration_ms", "fleet"]
    assert (batch["status"], batch["fleet"]) == (200, "acme") and batch["duration_ms"] > 0
    assert abs(datetime.fromisoformat(batch["time"]).timestamp() - time.time()) < 120
    assert (by_path[("POST", "/v1/warning")]["status"], by_path[("POST", "/v1/warning")]["fleet"]) == (401, None)
    start_up = stdout.read_text().splitlines()
    assert start_up[0] == f"csws: loading network 1 of 1: {TRACK_NET}"
    assert start_up[1].startswith("csws: loaded 1 network(s), 5 lanes, in ")
    assert start_up[2].startswith("csws: serving t7_left on http://127.0.0.1:")
    assert any(" INFO " in line or line.startswith("INFO:") for line in text.splitlines())  # --log-level info


class _Kept(logging.Handler):
    def __init__(self) -> None:
        super().__init__()
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(record.getMessage())


def test_the_text_access_log_is_one_plain_line():
    log, kept = AccessLog("text"), _Kept()
    ACCESS_LOGGER.addHandler(kept)
    try:
        log.record({"method": "GET", "path": "/healthz", "csws.fleet": "acme"}, 200, 0.0012)
    finally:
        ACCESS_LOGGER.removeHandler(kept)
    [line] = kept.lines
    assert line.endswith(" GET /healthz 200 1.200 ms fleet=acme")
    assert abs(datetime.fromisoformat(line.split(" ")[0]).timestamp() - time.time()) < 120
    with pytest.raises(ValueError, match="text or json"):
        AccessLog("xml")  # type: ignore[arg-type]


def test_log_level_and_access_log_are_checked_options():
    parser = build_parser()
    args = parser.parse_args(["serve", "--log-level", "debug", "--access-log"])
    assert (args.log_level, args.access_log) == ("debug", "text")
    assert parser.parse_args(["serve"]).log_level == "warning"
    with pytest.raises(SystemExit):
        parser.parse_args(["serve", "--access-log", "xml"])


# ------------------------------------------------------------------ compose.yaml


def _image_environment() -> dict[str, str]:
    """The variables the Dockerfile's ENV sets."""
    text = (ROOT / "Dockerfile").read_text().replace("\\\n", " ")
    words = [shlex.split(line)[1:] for line in text.splitlines() if line.startswith("ENV ")]
    return dict(pair.split("=", 1) for line in words for pair in line)


def _compose() -> dict:
    return yaml.safe_load((ROOT / "compose.yaml").read_text())


def test_compose_starts_csws_after_a_healthy_redis_that_keeps_every_write():
    services = _compose()["services"]
    assert set(services) == {"redis", "csws"}
    redis = services["redis"]
    assert redis["image"].startswith("redis:")
    assert redis["command"][redis["command"].index("--appendfsync") + 1] == "always"
    assert redis["healthcheck"]["test"][-1] == "ping"
    csws = services["csws"]
    assert csws["build"] == "." and (ROOT / "Dockerfile").exists()
    assert csws["depends_on"] == {"redis": {"condition": "service_healthy"}}
    assert set(_compose()["volumes"]) >= {volume.split(":")[0] for volume in redis["volumes"]}


def test_compose_s_command_is_a_csws_serve_the_service_accepts(monkeypatch):
    csws = _compose()["services"]["csws"]
    command = [str(word) for word in csws["command"]]
    assert command[:2] == ["csws", "serve"]
    args = build_parser().parse_args(command[1:])
    for name in [name for name in os.environ if name.startswith("CSWS_")]:
        monkeypatch.delenv(name)
    for name, value in _image_environment().items():  # what the image sets (Dockerfile ENV)
        monkeypatch.setenv(name, value)
    settings = settings_from_args(args)
    assert settings.state == "redis://redis:6379/0" and settings.host == "0.0.0.0" and settings.workers == 2
    assert args.access_log == "json"
    [published] = csws["ports"]
    assert published == f"{settings.port}:{settings.port}"
    keys_volume = next(volume for volume in csws["volumes"] if volume.startswith("./keys:"))
    assert settings.api_keys_file is not None and str(settings.api_keys_file.parent) == keys_volume.split(":")[1]
    assert "/readyz" in shlex.join(csws["healthcheck"]["test"])
