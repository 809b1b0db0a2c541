"""Real receivers of pushed events on loopback, for tests/test_push.py: a webhook receiver that fails, times out
and recovers on a script; a ``mosquitto`` (the Debian package; tests/system-packages.sh installs it) on a free port,
and a paho subscriber of it; and the events they receive."""

from __future__ import annotations

import hashlib
import hmac
import json
import shutil
import socket
import subprocess
import threading
import time
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import paho.mqtt.client as paho
from servers import free_port

from service.push.source import MemoryOutbox

FLEET = "acme"
#: A receiver refuses a signature whose time is further than this from its clock, s.
SIGNATURE_TOLERANCE_S = 300


def event_body(vehicle_id: str, seq: int, fleet: str = FLEET, level: int = 0, state: str = "") -> bytes:
    """An event as the outbox keeps it (its state by default active, standby at every third)."""
    state = state or ("active" if seq % 3 else "standby")
    body = {
        "fleet": fleet,
        "vehicle_id": vehicle_id,
        "seq": seq,
        "kind": "curve_level",
        "time": time.time(),
        "level": level,
        "state": state,
    }
    return json.dumps(body).encode()


def write_events(outbox: MemoryOutbox, vehicles: list[str], count: int, fleet: str = FLEET) -> None:
    """``count`` events of each vehicle, interleaved (1, 1, 1, 2, 2, 2, ...)."""
    for seq in range(1, count + 1):
        for vehicle in vehicles:
            outbox.write(fleet, vehicle, event_body(vehicle, seq, fleet, level=seq % 3))


class Receiver:
    """A webhook receiver on loopback: each POST is answered as ``script(number, key)`` says: (status, delay s)."""

    def __init__(self, script: Callable[[int, str], tuple[int, float]] = lambda number, key: (200, 0.0)) -> None:
        self.script = script
        self.requests: list[dict] = []
        self.lock = threading.Lock()
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def do_POST(self) -> None:  # noqa: N802 - http.server's name
                body = self.rfile.read(int(self.headers["Content-Length"]))
                key = self.headers["Idempotency-Key"]
                with receiver.lock:
                    number = len(receiver.requests) + 1
                    status, delay_s = receiver.script(number, key)
                    receiver.requests.append(
                        {
                            "key": key,
                            "signature": self.headers["X-CSWS-Signature"],
                            "body": body,
                            "status": status,
                            "arrived_s": time.time(),
                        }
                    )
                time.sleep(delay_s)
                try:
                    self.send_response(status)
                    self.send_header("Content-Length", "0")
                    self.end_headers()
                except OSError:
                    pass

            def log_message(self, *args) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/events"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def accepted(self) -> list[dict]:
        """The requests answered 2xx, in arrival order."""
        with self.lock:
            return [request for request in self.requests if 200 <= request["status"] < 300]

    def stop(self) -> None:
        self.server.shutdown()
        self.server.server_close()


def signature_holds(secret: str, request: dict) -> bool:
    """Whether a request's X-CSWS-Signature is the HMAC-SHA256 of ``t.`` + body, with a recent t."""
    fields = dict(part.split("=", 1) for part in request["signature"].split(","))
    expected = hmac.new(secret.encode(), fields["t"].encode() + b"." + request["body"], hashlib.sha256).hexdigest()
    return hmac.compare_digest(expected, fields["v1"]) and abs(time.time() - int(fields["t"])) <= SIGNATURE_TOLERANCE_S


def wait_until(condition: Callable[[], bool], timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.02)


class Mosquitto:
    """A real ``mosquitto`` on a free loopback port, anonymous, without persistence."""

    def __init__(self, folder: Path) -> None:
        binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
        if not Path(binary).exists():
            raise RuntimeError("the MQTT tests need mosquitto: apt-get install mosquitto (tests/system-packages.sh)")
        self.port = free_port()
        self.config = folder / "mosquitto.conf"
        self.config.write_text(f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
        self.process: subprocess.Popen[bytes]
        self.start()

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self) -> None:
        binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
        self.process = subprocess.Popen(
            [binary, "-c", str(self.config)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        wait_until(self._answers, 10.0)

    def _answers(self) -> bool:
        try:
            socket.create_connection(("127.0.0.1", self.port), 0.2).close()
            return True
        except OSError:
            return False

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            self.process.wait(timeout=10)


class Subscriber:
    """A paho client that records the messages of ``topic`` (QoS 1) as (topic, payload, retained)."""

    def __init__(self, broker: Mosquitto, topic: str) -> None:
        self.messages: list[tuple[str, bytes, bool]] = []
        self.subscribed = threading.Event()
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2)
        self.client.on_message = lambda client, data, message: self.messages.append(
            (message.topic, message.payload, bool(message.retain))
        )
        self.client.on_subscribe = lambda *args: self.subscribed.set()
        self.client.on_connect = lambda client, *args: client.subscribe(topic, qos=1)
        self.client.connect("127.0.0.1", broker.port)
        self.client.loop_start()
        assert self.subscribed.wait(10.0)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()
