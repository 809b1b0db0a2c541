"""``csws jt808`` (the JT/T 808 gateway) and ``csws terminals`` (the terminals it admits)."""

from __future__ import annotations

import argparse
import asyncio
import cProfile
import os
import ssl
import sys
import time
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any

from csws.cli import deferred
from csws.cli.argtypes import positive_float, positive_int

__all__ = [
    "EVENT_LOOPS",
    "add_commands",
    "loop_factory",
    "main",
    "run_profiled",
    "simulate_command",
    "terminals_command",
]

#: The environment variable naming the terminal file when --terminals is not given.
TERMINALS_ENV = "CSWS_JT808_TERMINALS_FILE"
#: The event loops ``csws jt808 --loop`` runs on.
EVENT_LOOPS = ("auto", "uvloop", "asyncio")


def loop_factory(name: str) -> Callable[[], asyncio.AbstractEventLoop] | None:
    """The factory of the event loop ``name`` (:data:`EVENT_LOOPS`); None for asyncio's own.

    ``auto`` takes uvloop where it is installed (it is not on Windows) and asyncio's loop otherwise.
    """
    if name == "asyncio":
        return None
    try:
        import uvloop
    except ImportError:
        if name == "uvloop":
            raise ValueError("--loop uvloop: uvloop is not installed (pip install uvloop)") from None
        return None
    return uvloop.new_event_loop


def run_profiled(
    main: Coroutine[Any, Any, None], factory: Callable[[], asyncio.AbstractEventLoop] | None, profile: Path | None
) -> None:
    """Run ``main`` on a new event loop of ``factory``; with ``profile``, a cProfile of this thread's CPU time (the
    event loop's side: reading, frames, responses, writes) is written there when it ends."""
    profiler = cProfile.Profile(time.thread_time_ns, 1e-9) if profile is not None else None
    if profiler is not None:
        profiler.enable()
    try:
        with asyncio.Runner(loop_factory=factory) as runner:
            runner.run(main)
    finally:
        if profiler is not None and profile is not None:
            profiler.disable()
            profiler.dump_stats(profile)


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws jt808`` and ``csws terminals`` (an entry point of the ``csws.commands`` group)."""
    gateway = commands.add_parser(
        "jt808",
        help="serve JT/T 808 terminals over TCP: location reports in, warnings back as text and speech",
        description="The JT/T 808 (2013, 2019) gateway: admitted terminals (csws terminals add) report their "
        "positions; each report is answered like POST /v1/warning, on the same networks and state store, and "
        "the driver is told by text message (0x8300) when the warning changes. Network and state options and "
        "their CSWS_* environment variables are those of csws serve.",
    )
    gateway.add_argument("--net", type=Path, action="append", default=None, metavar="FILE", help="a SUMO network")
    gateway.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    gateway.add_argument("--port", type=int, default=6808, help="TCP port (default 6808)")
    gateway.add_argument("--state", default=None, metavar="URL", help="redis://HOST:PORT/DB, shared by gateways")
    gateway.add_argument("--state-db", default=None, metavar="FILE", help="SQLite file of the sessions")
    gateway.add_argument(
        "--terminals", type=Path, default=None, metavar="FILE", help=f"terminal file (${TERMINALS_ENV})"
    )
    gateway.add_argument("--texts", type=Path, default=None, metavar="FILE", help="the drivers' texts per fleet (JSON)")
    gateway.add_argument(
        "--warning-settings",
        type=Path,
        default=None,
        metavar="FILE",
        help="the curve warning's update period and release rule per fleet, as csws serve's",
    )
    gateway.add_argument(
        "--no-tracking",
        action="append",
        default=[],
        metavar="FLEET",
        help="never ask this fleet's slow terminals for 1 s reports near a curve (0x8202); '*' for every fleet",
    )
    gateway.add_argument(
        "--idle-s", type=positive_float, default=180.0, help="close a connection silent this long, s (default 180)"
    )
    gateway.add_argument(
        "--max-connections",
        type=positive_int,
        default=20_000,
        help="close connections beyond this many at once (default 20,000)",
    )
    gateway.add_argument(
        "--frames-per-s",
        type=positive_float,
        default=20.0,
        help="frames a second one connection may send on average; the excess is dropped (default 20)",
    )
    gateway.add_argument(
        "--frames-burst",
        type=_burst,
        default=60.0,
        help="frames one connection may send at once, 1 or more (default 60)",
    )
    gateway.add_argument("--tls-cert", type=Path, default=None, metavar="PEM", help="serve TLS with this certificate")
    gateway.add_argument("--tls-key", type=Path, default=None, metavar="PEM", help="the certificate's private key")
    gateway.add_argument(
        "--loop",
        choices=EVENT_LOOPS,
        default="auto",
        help="the event loop: uvloop (libuv), asyncio (the standard one), or auto: uvloop where installed",
    )
    gateway.add_argument(
        "--profile", type=Path, default=None, metavar="FILE", help="write a cProfile of the event loop's thread at exit"
    )
    gateway.set_defaults(handler=deferred("service.jt808_cli"))
    simulator = commands.add_parser(
        "jt808-sim",
        help="drive simulated JT/T 808 terminals along recorded tracks against a gateway (a smoke test)",
        description="Each phone of the tracks file connects, registers, authenticates and reports at its "
        "track's times; prints what came back. Exit 1 if a terminal was refused.",
    )
    simulator.add_argument("tracks", type=Path, help="CSV: phone,time_s,lon_deg,lat_deg,speed_kmh,heading_deg")
    simulator.add_argument("--gateway", default="127.0.0.1:6808", metavar="HOST:PORT", help="the gateway")
    simulator.add_argument("--ramp-s", type=float, default=5.0, help="connect the terminals over this long, s")
    simulator.set_defaults(handler=deferred("service.jt808_cli", "simulate_command"))
    _add_terminals(commands)


def _add_terminals(commands: argparse._SubParsersAction) -> None:
    """Add ``csws terminals add | list | revoke``."""
    terminals = commands.add_parser("terminals", help="manage the JT/T 808 terminals the gateway admits")
    actions = terminals.add_subparsers(dest="terminals_command", metavar="ACTION", required=True)
    add = actions.add_parser("add", help="admit a terminal for a vehicle of a fleet")
    add.add_argument("fleet", help="the fleet (as its API keys name it)")
    add.add_argument("phone", help="the terminal's phone number (up to 20 digits)")
    add.add_argument("--category", required=True, help="vehicle category: M1, M2, M3, N or O")
    add.add_argument("--plate", default="", help="the plate (GBK text, e.g. 京A12345)")
    add.add_argument("--vehicle-id", default=None, help="the vehicle id in the HTTP API (default: plate, else phone)")
    listing = actions.add_parser("list", help="list the terminals")
    revoke = actions.add_parser("revoke", help="refuse a terminal from its next message on (no restart)")
    revoke.add_argument("phone", help="the terminal's phone number")
    for parser in (add, listing, revoke):
        parser.add_argument("--file", type=Path, default=None, help=f"the terminal file (default ${TERMINALS_ENV})")
        parser.set_defaults(handler=deferred("service.jt808_cli", "terminals_command"))


def _terminal_file(given: Path | None) -> Path:
    path = given or (Path(os.environ[TERMINALS_ENV]) if os.environ.get(TERMINALS_ENV) else None)
    if path is None:
        raise ValueError(f"give the terminal file: --file FILE (--terminals for csws jt808), or set {TERMINALS_ENV}")
    return path


def terminals_command(args: argparse.Namespace) -> int:
    """``csws terminals add | list | revoke``."""
    from csws.gateways.jt808.terminals import TerminalList, add_terminal, revoke_terminal

    path = _terminal_file(args.file)
    if args.terminals_command == "add":
        terminal = add_terminal(
            path, args.fleet, args.phone, vehicle_id=args.vehicle_id, category=args.category, plate=args.plate
        )
        print(
            f"csws: terminal {terminal.phone} speaks for {terminal.fleet}/{terminal.vehicle_id} ({terminal.category})"
        )
    elif args.terminals_command == "revoke":
        terminal = revoke_terminal(path, args.phone)
        print(f"csws: terminal {terminal.phone} of {terminal.fleet} revoked")
    else:
        for terminal in TerminalList(path):
            status = "revoked" if terminal.revoked else "admitted"
            print(
                f"{terminal.phone}\t{terminal.fleet}\t{terminal.vehicle_id}\t{terminal.category}\t{terminal.plate}\t{status}"
            )
    return 0


def _tls(args: argparse.Namespace) -> ssl.SSLContext | None:
    if args.tls_cert is None and args.tls_key is None:
        return None
    if args.tls_cert is None or args.tls_key is None:
        raise ValueError("TLS needs both --tls-cert and --tls-key")
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    try:
        context.load_cert_chain(args.tls_cert, args.tls_key)
    except (OSError, ssl.SSLError) as error:
        raise ValueError(f"cannot load the TLS certificate: {error}") from None
    return context


def _burst(text: str) -> float:
    """``--frames-burst``: a finite number of frames, at least 1 (below, no frame is ever let through)."""
    value = positive_float(text)
    if value < 1.0:
        raise argparse.ArgumentTypeError(f"must be at least 1 frame: {text!r}")
    return value


def main(args: argparse.Namespace) -> int:
    """``csws jt808``: build the warning service as ``csws serve`` does, then serve terminals until interrupted."""
    from csws.gateways.jt808.terminals import TerminalList
    from csws.gateways.jt808.texts import load_fleet_texts

    from .app import create_app
    from .jt808 import Gateway
    from .jt808_settings import GatewaySettings
    from .run import settings_from_args

    terminals = TerminalList(_terminal_file(args.terminals))
    texts = load_fleet_texts(args.texts) if args.texts is not None else {}
    tls = _tls(args)
    factory = loop_factory(args.loop)
    service_args = argparse.Namespace(
        net=args.net, state=args.state, state_db=args.state_db, warning_settings=args.warning_settings
    )
    # Terminals are admitted by the terminal file; the fleets' API keys are the HTTP API's, not read here.
    state = create_app(settings_from_args(service_args).model_copy(update={"api_keys_file": None})).state
    if not any(network.road_map.has_projection for network in state.service.networks):
        state.work.close()
        state.store.close()
        print("csws: error: no served network is geo-referenced, and JT/T 808 reports give lon/lat", file=sys.stderr)
        return 2
    settings = GatewaySettings(
        host=args.host,
        port=args.port,
        idle_s=args.idle_s,
        frames_per_s=args.frames_per_s,
        frames_burst=args.frames_burst,
        max_connections=args.max_connections,
        fleet_texts=texts,
        untracked_fleets=frozenset(args.no_tracking),
    )
    gateway = Gateway(state.service, state.work, terminals, settings)

    def ready(port: int) -> None:
        networks = len(state.service.networks)
        loop = type(asyncio.get_running_loop()).__module__.split(".")[0]
        print(f"csws: JT/T 808 gateway for {networks} network(s) on {args.host}:{port}", flush=True)
        print(f"csws: event loop {loop}", flush=True)

    try:
        run_profiled(gateway.serve(tls, ready), factory, args.profile)
    except KeyboardInterrupt:
        pass
    except OSError as error:
        print(f"csws: cannot listen on {args.host}:{args.port}: {error.strerror or error}", file=sys.stderr)
        return 1
    finally:
        state.work.close()
        state.store.close()
        print(f"csws: JT/T 808 gateway stopped: {gateway.summary()}", flush=True)
        print(f"csws: {gateway.stages()}", flush=True)
    return 0


def simulate_command(args: argparse.Namespace) -> int:
    """``csws jt808-sim``: run the tracks' terminals against the gateway and print what they saw."""
    from collections import Counter

    import numpy as np

    from csws.gateways.jt808.simulator import read_tracks, simulate

    host, _, port = args.gateway.rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"--gateway is HOST:PORT, got {args.gateway!r}")
    terminals = read_tracks(args.tracks)
    stats = asyncio.run(simulate(terminals, host, int(port), args.ramp_s))
    answered = np.array(stats.response_s) * 1000.0
    print(
        f"csws: {len(terminals)} terminal(s), {stats.refused} refused, {len(answered)} report(s) answered, "
        f"{stats.tracking_requests} tracking request(s) honoured"
    )
    if len(answered):
        print(f"csws: 0x8001 after p50 {np.percentile(answered, 50):.1f} ms, p99 {np.percentile(answered, 99):.1f} ms")
    for text, count in Counter(stats.texts).most_common():
        print(f"csws: {count} x 0x8300 {text}")
    return 1 if stats.refused else 0
