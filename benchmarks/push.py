"""Push of events to a webhook receiver and to mosquitto, 10,000 vehicles at 1 Hz, on loopback.

A writer appends each vehicle's event once a second to an outbox, spread evenly over the second: an
in-memory one (:class:`service.push.source.MemoryOutbox`), and the SQLite state store's
(:class:`service.store.sqlite.SQLiteStore`), written through ``StateStore.write`` with each vehicle's
session as the service writes them (a tenth of the vehicles a transaction, as a batch request's), from
a process of their own (as the service's workers write), so that the figures of the second include the
store's writes and the dispatcher's reads of them. The dispatcher of :func:`service.push.start_push`
runs in this process as in a worker of the service.
The receivers run in processes of their own: a minimal HTTP/1.1 receiver on asyncio (answers 200 at
once, keeps each body's arrival time) and a paho subscriber of a real ``mosquitto`` (QoS 1).

Measured, for each: events delivered per second, events lost (written, never arrived), vehicles whose
events arrived out of order, and the p50/p99 from an event's write to its arrival. For the webhook,
every signature is checked afterwards with the test's own HMAC-SHA256.

Run with ``python -m benchmarks.push [VEHICLES] [SECONDS]``.
"""

from __future__ import annotations

import argparse
import asyncio
import hashlib
import hmac
import json
import multiprocessing
import os
import re
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.command import arguments
from benchmarks.rows import Row, at_least, at_most
from service.push import PushConfig, start_push
from service.push.source import EventSource, MemoryOutbox
from service.push.targets import add_webhook
from service.store import NewEvent, StateStore, VehicleWrite
from service.store.sqlite import SQLiteStore

__all__ = ["BENCH_VEHICLES", "TARGET_P99_MS", "rows", "run"]

#: The issue's targets: 10,000 vehicles at 1 Hz, p99 from the event to its arrival within 50 ms on loopback.
BENCH_VEHICLES, TARGET_P99_MS = 10_000, 50.0
#: How long the writer writes, s, and how long the receivers may take for the last events after it.
WRITE_S, DRAIN_S = 10.0, 20.0
#: Time for the dispatchers to connect before the first write (a service's are long up when events come), s.
WARM_UP_S = 1.0
#: Keeping up: at least this share of the offered rate, over the writes and the last arrivals after them.
KEEPING_UP = 0.98
FLEET = "bench"
_LENGTH = re.compile(rb"content-length:\s*(\d+)", re.IGNORECASE)
_SIGNATURE = re.compile(rb"x-csws-signature:\s*([^\r\n]+)", re.IGNORECASE)


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _receive_http(port: int, out: str, stop: Any) -> None:
    """The webhook receiver's process: keep each POST's arrival time, body and signature; write them at ``stop``."""
    arrivals: list[tuple[float, bytes, bytes]] = []

    async def handle(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while True:
                head = await reader.readuntil(b"\r\n\r\n")
                length = _LENGTH.search(head)
                body = await reader.readexactly(int(length.group(1)) if length else 0)
                signature = _SIGNATURE.search(head)
                arrivals.append((time.time(), body, signature.group(1) if signature else b""))
                writer.write(b"HTTP/1.1 200 OK\r\nContent-Length: 0\r\n\r\n")
        except (asyncio.IncompleteReadError, ConnectionError):
            writer.close()

    async def serve() -> None:
        server = await asyncio.start_server(handle, "127.0.0.1", port)
        async with server:
            while not stop.is_set():
                await asyncio.sleep(0.1)

    asyncio.run(serve())
    _write_arrivals(out, [(at, body, sig.decode()) for at, body, sig in arrivals])


def _receive_mqtt(port: int, out: str, ready: Any, stop: Any) -> None:
    """The MQTT subscriber's process: keep each event's arrival time and payload; write them at ``stop``."""
    import paho.mqtt.client as paho

    arrivals: list[tuple[float, bytes, str]] = []
    client = paho.Client(paho.CallbackAPIVersion.VERSION2)
    client.on_message = lambda _client, _data, message: arrivals.append((time.time(), bytes(message.payload), ""))
    client.on_connect = lambda the_client, *args: the_client.subscribe(f"csws/{FLEET}/+/events", qos=1)
    client.on_subscribe = lambda *args: ready.set()
    client.connect("127.0.0.1", port)
    client.loop_start()
    stop.wait()
    client.loop_stop()
    _write_arrivals(out, arrivals)


def _write_arrivals(out: str, arrivals: list[tuple[float, bytes, str]]) -> None:
    """Each arrival as a JSON line: its time, the event's vehicle, number and write time, and the signature."""
    with open(out, "w") as file:
        for at, body, signature in arrivals:
            event = json.loads(body)
            row = [at, event["vehicle_id"], event["seq"], event["time"], signature, body.decode()]
            file.write(json.dumps(row) + "\n")


#: The outboxes the runs read: in memory, and the SQLite state store's.
OUTBOXES = ("memory", "sqlite")
#: The writes a second into each outbox: in memory a hundredth of the vehicles every 10 ms; into the store a
#: tenth every 100 ms, one transaction each, as batch requests of a thousand vehicles write them (every
#: transaction with events is synced to disk, some 10 ms here, so a hundred a second would be the disk's limit).
SLOTS_PER_S = {"memory": 100, "sqlite": 10}


class _StoreWriter:
    """Writes a slot's events into a state store as the service does: each with its vehicle's session, in one
    ``StateStore.write`` (one transaction), each vehicle at the session version its last write left."""

    def __init__(self, store: StateStore) -> None:
        self.store = store
        self.versions: dict[str, int] = {}

    def write_slot(self, events: list[tuple[str, int, float, bytes]]) -> None:
        """Write ``events`` (vehicle id, number, time, JSON) of :data:`FLEET`; raise if a write was refused."""
        writes = {}
        for vehicle_id, seq, time_s, body in events:
            key = f"{FLEET}/{vehicle_id}"
            event = NewEvent(FLEET, seq, time_s, body)
            writes[key] = VehicleWrite(self.versions.get(key, 0), b"session", events=(event,))
        if refused := self.store.write(writes):
            raise RuntimeError(f"{len(refused)} session writes refused")
        for key in writes:
            self.versions[key] = self.versions.get(key, 0) + 1


class _MemoryWriter:
    """Writes a slot's events into a :class:`MemoryOutbox`."""

    def __init__(self, outbox: MemoryOutbox) -> None:
        self.outbox = outbox

    def write_slot(self, events: list[tuple[str, int, float, bytes]]) -> None:
        for vehicle_id, _seq, _time_s, body in events:
            self.outbox.write(FLEET, vehicle_id, body)


def _write(outbox: _StoreWriter | _MemoryWriter, vehicles: int, seconds: float, slots: int) -> int:
    """Write each vehicle's event once a second for ``seconds``, spread over the second; the events written."""
    written, started = 0, time.time()
    per_slot = vehicles / slots
    for tick in range(int(seconds * slots)):
        while time.time() < started + tick / slots:
            time.sleep(0.001)
        seq = tick // slots + 1
        first, last = int((tick % slots) * per_slot), int((tick % slots + 1) * per_slot)
        events = []
        for vehicle in range(first, last):
            now_s = time.time()
            body = {
                "fleet": FLEET,
                "vehicle_id": f"v{vehicle}",
                "seq": seq,
                "kind": "state",
                "time": now_s,
                "level": 0,
                "state": "active",
            }
            events.append((f"v{vehicle}", seq, now_s, json.dumps(body).encode()))
        outbox.write_slot(events)
        written += len(events)
    return written


def _write_into_store(path: Path, vehicles: int, seconds: float, written: Any) -> None:
    """A writer's process: :func:`_write` into the SQLite store at ``path``; the events written in ``written``."""
    store = SQLiteStore(path, 600.0)
    try:
        written.value = _write(_StoreWriter(store), vehicles, seconds, SLOTS_PER_S["sqlite"])
    finally:
        store.close()


def _write_elsewhere(path: Path, vehicles: int, seconds: float) -> int:
    """:func:`_write` into the SQLite store at ``path`` from a process of its own, as the service's workers write
    while push reads in one of them; the events written."""
    spawn = multiprocessing.get_context("spawn")
    written = spawn.Value("q", 0)
    writer = spawn.Process(target=_write_into_store, args=(path, vehicles, seconds, written))
    writer.start()
    writer.join(seconds + 60.0)
    if writer.exitcode != 0:
        raise RuntimeError(f"the writer's process ended with {writer.exitcode}")
    return int(written.value)


def _judged(out: str, written: int, secret: str | None) -> dict[str, Any]:
    """What arrived: delivered per second, lost, vehicles out of order, latency percentiles, bad signatures."""
    rows = [json.loads(line) for line in Path(out).read_text().splitlines()]
    seen: dict[str, list[int]] = {}
    latencies = np.array([row[0] - row[3] for row in rows]) * 1000.0
    for row in rows:
        seen.setdefault(row[1], []).append(row[2])
    unique = sum(len(set(numbers)) for numbers in seen.values())
    out_of_order = sum(numbers != sorted(numbers) for numbers in seen.values())
    bad = 0
    if secret is not None:
        for row in rows:
            fields = dict(part.split("=", 1) for part in row[4].split(","))
            digest = hmac.new(secret.encode(), f"{fields['t']}.".encode() + row[5].encode(), hashlib.sha256)
            bad += not hmac.compare_digest(digest.hexdigest(), fields["v1"])
    span_s = max(row[0] for row in rows) - min(row[3] for row in rows) if rows else 1.0
    return {
        "written": written,
        "arrived": len(rows),
        "lost": written - unique,
        "out_of_order_vehicles": out_of_order,
        "delivered_per_s": unique / span_s,
        "p50_ms": float(np.percentile(latencies, 50)) if rows else float("nan"),
        "p99_ms": float(np.percentile(latencies, 99)) if rows else float("nan"),
        "bad_signatures": bad,
    }


def _one_run(sink: str, vehicles: int, seconds: float, folder: Path, kind: str = "memory") -> dict[str, Any]:
    """Write for ``seconds`` into the outbox ``kind`` (memory or sqlite) with push to ``sink`` (webhook or mqtt)
    and judge what arrived."""
    spawn = multiprocessing.get_context("spawn")
    folder = folder / f"{sink}-{kind}"
    folder.mkdir()
    stop, ready, out, port = spawn.Event(), spawn.Event(), str(folder / f"{sink}.jsonl"), _free_port()
    broker, secret, config = None, None, PushConfig(str(folder / f"{sink}.sqlite3"))
    if sink == "webhook":
        receiver = spawn.Process(target=_receive_http, args=(port, out, stop))
        receiver.start()
        _wait_for_port(port)
        secret = add_webhook(folder / "webhooks.json", FLEET, f"http://127.0.0.1:{port}/csws", allow_private=True)
        config = PushConfig(config.state_db, webhooks_file=folder / "webhooks.json", allow_private=True)
    else:
        broker = _start_mosquitto(port, folder)
        receiver = spawn.Process(target=_receive_mqtt, args=(port, out, ready, stop))
        receiver.start()
        ready.wait(30)
        config = PushConfig(config.state_db, mqtt_url=f"mqtt://127.0.0.1:{port}")
    source: EventSource
    if kind == "sqlite":
        source = SQLiteStore(folder / "vehicles.sqlite3", 600.0)
    else:
        source = MemoryOutbox()
    stop_push = start_push(config, source)
    time.sleep(WARM_UP_S)
    try:
        if isinstance(source, MemoryOutbox):
            written = _write(_MemoryWriter(source), vehicles, seconds, SLOTS_PER_S[kind])
        else:
            written = _write_elsewhere(folder / "vehicles.sqlite3", vehicles, seconds)
        deadline = time.monotonic() + DRAIN_S
        while time.monotonic() < deadline and _pushed(config, sink) < written:
            time.sleep(0.1)
        time.sleep(0.5)
    finally:
        stop_push()
        stop.set()
        receiver.join(60)
        if broker is not None:
            broker.terminate()
            broker.wait(10)
        if isinstance(source, SQLiteStore):
            source.close()
    return _judged(out, written, secret)


def _pushed(config: PushConfig, sink: str) -> int:
    """How far the cursor of ``sink`` went: the events handed out."""
    from service.push.state import PushState

    state = PushState(config.state_db)
    try:
        cursor = state.cursor("webhooks" if sink == "webhook" else "mqtt")
    finally:
        state.close()
    return int(cursor) if cursor else 0


def _wait_for_port(port: int) -> None:
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), 0.2).close()
            return
        except OSError:
            time.sleep(0.05)
    raise RuntimeError(f"nothing listens on port {port}")


def _start_mosquitto(port: int, folder: Path) -> subprocess.Popen[bytes]:
    """A real mosquitto on ``port``, anonymous, without persistence."""
    binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
    if not os.path.exists(binary):
        raise RuntimeError("the MQTT benchmark needs mosquitto: apt-get install mosquitto")
    config = folder / "mosquitto.conf"
    config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\nmax_queued_messages 0\n")
    process = subprocess.Popen([binary, "-c", str(config)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _wait_for_port(port)
    return process


def run(vehicles: int = BENCH_VEHICLES, seconds: float = WRITE_S, outboxes: tuple[str, ...] = OUTBOXES) -> dict:
    """The runs of each sink and outbox, one after the other, with the machine's load average at the start."""
    with tempfile.TemporaryDirectory(prefix="csws-push-bench-") as folder:
        load = os.getloadavg()[0]
        figures = {
            _name(sink, kind): _one_run(sink, vehicles, seconds, Path(folder), kind)
            for kind in outboxes
            for sink in ("webhook", "mqtt")
        }
    return {"vehicles": vehicles, "seconds": seconds, "load_average": load, **figures}


def _name(sink: str, kind: str) -> str:
    """The figures' name of a run: the sink, with ``-sqlite`` when it read the SQLite store's outbox."""
    return sink if kind == "memory" else f"{sink}-{kind}"


def rows(figures: dict[str, Any]) -> list[Row]:
    """The table's rows: rate, loss, order and p99 of each sink."""
    result: list[Row] = []
    size = f"{figures['vehicles']:,} vehicles at 1 Hz for {figures['seconds']:g} s, load {figures['load_average']:.1f}"
    for sink in [name for name in figures if name.partition("-")[0] in ("webhook", "mqtt")]:
        each = figures[sink]
        offered = figures["vehicles"]
        result += [
            at_least(f"push {sink}: events delivered per s", each["delivered_per_s"], KEEPING_UP * offered, size),
            at_most(
                f"push {sink}: events not arrived {DRAIN_S:g} s after the writes",
                each["lost"],
                0,
                f"{each['written']:,} written",
            ),
            at_most(f"push {sink}: vehicles out of order", each["out_of_order_vehicles"], 0),
            at_most(
                f"push {sink}: write to arrival p99, ms", each["p99_ms"], TARGET_P99_MS, f"p50 {each['p50_ms']:.1f} ms"
            ),
        ]
        if sink.startswith("webhook"):
            result.append(at_most(f"push {sink}: signatures that do not verify", each["bad_signatures"], 0))
    return result


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    """The fleet's size and how long its events are written."""
    parser.add_argument("vehicles", type=int, nargs="?", default=BENCH_VEHICLES, help="vehicles, 1 event/s each")
    parser.add_argument("seconds", type=float, nargs="?", default=WRITE_S, help="how long events are written, s")


def main() -> None:
    """Print the rows ``python -m benchmarks`` shows of this benchmark, then each sink's figures."""
    from benchmarks.rows import table

    given = arguments("benchmarks.push", __doc__, _add_arguments)
    measured = run(given.vehicles, given.seconds)
    print(table(rows(measured)))
    print(json.dumps({name: value for name, value in measured.items() if isinstance(value, dict)}, indent=1))


if __name__ == "__main__":
    main()
