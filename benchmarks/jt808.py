"""The JT/T 808 gateway under a fleet of terminals reporting at 1 Hz on the bundled city.

SUMO drives a fleet on Bad Hersfeld (:func:`benchmarks.telematics_fleet.drive_fleet`); each
vehicle's trajectory, sampled once a second and turned into lon/lat, is a recorded track. The
simulated terminals (:mod:`csws.gateways.jt808.simulator`) each replay one of those tracks (more
terminals than vehicles share tracks, each on its own connection and vehicle id), connect
spread over a ramp, register, authenticate and report at 1 Hz to a real ``csws jt808`` process
with a SQLite state store; the terminals run in this process on the same machine.

Measured: reports answered, the p50/p99 from a report's last byte to its general response
(``0x8001``) and to a text message (``0x8300``) where one was due, the gateway's resident memory
per connected terminal, and its CPU seconds per report.

Run with ``python -m benchmarks.jt808 [TERMINALS]``; ``--scaleout-only`` runs only one gateway against two on
one Redis, ``--single`` only the one gateway, on the event loop ``--loop`` names, its loop thread profiled with
``--profile FILE`` (``--help`` lists the options). The gateway's CPU is also given per thread: the event loop's
(in user and kernel time) and the others' (the work thread's).
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.rows import Row, at_least, at_most, context
from benchmarks.servers import cpu_s, memory_mb, redis_server
from benchmarks.telematics_fleet import drive_fleet, lonlat
from csws.gateways.jt808.latency import parse_stages
from csws.gateways.jt808.simulator import SimulatedTerminal, Track, simulate
from csws.gateways.jt808.terminals import NewTerminal, add_terminals
from csws.networks import networks_dir

__all__ = [
    "BENCH_TERMINALS",
    "NET",
    "VEHICLES",
    "TARGET_P99_MS",
    "TARGET_SCALEOUT",
    "city_tracks",
    "rows",
    "run",
    "run_all",
    "run_scaleout",
    "scaleout_bound",
    "summary_counts",
]

NET = networks_dir() / "badhersfeld.net.xml.gz"
#: The issue's targets: p99 from a report to its 0x8300 within 100 ms; 10,000 terminals on one 2-core node.
TARGET_P99_MS, TARGET_TERMINALS, TARGET_SCALEOUT = 100.0, 10_000, 1.8
#: Terminals in the full run: what one 2-core machine carries with the terminals' own simulation on it.
BENCH_TERMINALS = 2000
#: How long each terminal reports, s, and how many SUMO vehicles give the tracks.
REPORT_S, VEHICLES = 60.0, 200
#: How much faster than recorded the scale-out's terminals replay their tracks, tried in turn, and the share of
#: the reports offered one gateway must shed to count as taking all it can.
SCALEOUT_SPEEDUPS, SATURATED_SHARE = (5.0, 10.0, 20.0), 0.05
#: Seconds the gateway may take to load the network.
STARTUP_TIMEOUT_S = 180.0


def city_tracks(vehicles: int, duration_s: float) -> list[Track]:
    """1 Hz tracks of a SUMO fleet on the bundled city, each at least half the run long."""
    trajectories = drive_fleet(NET, vehicles, duration_s + 30.0, seed=808)
    ten = trajectories.step % 10 == 0
    converted = lonlat(NET, trajectories.x_m, trajectories.y_m)
    assert converted is not None, "the bundled city is geo-referenced"
    lon, lat = converted
    tracks = []
    for vehicle in range(len(trajectories.vehicle_ids)):
        rows = np.flatnonzero(ten & (trajectories.vehicle == vehicle))
        if len(rows) >= duration_s / 2:
            steps = trajectories.step[rows]
            tracks.append(
                Track(
                    time_s=(steps - steps[0]) * 0.1,
                    lon_deg=lon[rows],
                    lat_deg=lat[rows],
                    speed_kmh=trajectories.speed_mps[rows] * 3.6,
                    heading_deg=trajectories.heading_deg[rows],
                )
            )
    return tracks


def _gateway(terminals_file: Path, *state: str) -> tuple[subprocess.Popen, int]:
    """A ``csws jt808`` process on a free port with the state (and other) options ``state``, ready: it and its port."""
    command = [sys.executable, "-m", "csws", "jt808", "--net", str(NET), "--port", "0"]
    process = subprocess.Popen(
        [*command, "--terminals", str(terminals_file), *state],
        stdout=subprocess.PIPE,
        text=True,
        cwd=Path(__file__).resolve().parents[1],
    )
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    assert process.stdout is not None
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        if "JT/T 808 gateway for" in line:
            return process, int(line.rsplit(":", 1)[1])
    process.kill()
    raise RuntimeError("csws jt808 did not start")


def _stopped(process: subprocess.Popen) -> tuple[int, int, dict[str, tuple[float, float]]]:
    """Stop a gateway (SIGTERM); the reports it evaluated and shed, and its stage times (p50, p99 ms), from its
    last lines."""
    process.terminate()
    output, _ = process.communicate(timeout=60)
    return *summary_counts(output), parse_stages(output)


def summary_counts(output: str) -> tuple[int, int]:
    """The reports evaluated and shed that a gateway's summary line (``Gateway.summary``) in ``output`` gives.

    Raises
    ------
    RuntimeError
        Where ``output`` has no summary line.
    """
    counts = re.search(r"(\d+) report\(s\) evaluated, (\d+) shed", output)
    if counts is None:
        raise RuntimeError(f"csws jt808 stopped without its summary line: {output[-300:]!r}")
    return int(counts.group(1)), int(counts.group(2))


async def _loop_lag(lags_s: list[float], period_s: float = 0.01) -> None:
    """Sample how late this event loop wakes a sleeper: the terminals' own delay in what they time."""
    while True:
        asked = time.perf_counter()
        await asyncio.sleep(period_s)
        lags_s.append(time.perf_counter() - asked - period_s)


def _waited_s(pid: int) -> float:
    """Seconds the threads of process ``pid`` have spent runnable but waiting for a core (``schedstat``)."""
    total_ns = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            total_ns += int((task / "schedstat").read_text().split()[1])
        except (OSError, IndexError, ValueError):
            continue  # a thread that ended meanwhile
    return total_ns / 1e9


def _thread_cpu_s(pid: int) -> tuple[float, float, float]:
    """CPU seconds process ``pid`` used so far: its main thread's (the event loop's) in user and in kernel mode
    (the kernel's share is mostly the sockets' reads and writes), and all its other threads' (the work thread that
    answers groups, the state store's)."""
    user = kernel = others = 0.0
    tick_s = 1.0 / os.sysconf("SC_CLK_TCK")
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # a thread that ended meanwhile
        if task.name == str(pid):
            user, kernel = int(fields[11]) * tick_s, int(fields[12]) * tick_s
        else:
            others += (int(fields[11]) + int(fields[12])) * tick_s
    return user, kernel, others


def _percentile_ms(values: list[float], q: float) -> float:
    return float(np.percentile(np.array(values) * 1000.0, q)) if values else float("nan")


def run(terminals: int = BENCH_TERMINALS, report_s: float = REPORT_S, *gateway_options: str) -> dict[str, Any]:
    """Drive ``terminals`` simulated terminals for ``report_s`` against one gateway started with ``gateway_options``
    (e.g. ``--loop asyncio``); the figures."""
    tracks = city_tracks(VEHICLES, report_s)
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        phones = [f"1380{i:07d}" for i in range(terminals)]
        add_terminals(folder / "terminals.json", "bench", [NewTerminal(p, "N", f"t{p}") for p in phones])
        process, port = _gateway(folder / "terminals.json", "--state-db", str(folder / "state.db"), *gateway_options)
        try:
            idle_mb, _ = memory_mb(process.pid)
            cpu_before, waited_before = cpu_s([process.pid]), _waited_s(process.pid)
            threads_before = _thread_cpu_s(process.pid)
            simulated = [
                SimulatedTerminal(phone, _cut(tracks[i % len(tracks)], report_s)) for i, phone in enumerate(phones)
            ]
            peak, lags_s = {"mb": idle_mb}, list[float]()

            async def watched() -> Any:
                async def watch() -> None:
                    while True:
                        peak["mb"] = max(peak["mb"], memory_mb(process.pid)[0])
                        await asyncio.sleep(1.0)

                watchers = [asyncio.create_task(watch()), asyncio.create_task(_loop_lag(lags_s))]
                try:
                    return await simulate(simulated, "127.0.0.1", port, ramp_s=min(30.0, terminals / 200.0))
                finally:
                    for watcher in watchers:
                        watcher.cancel()

            started, simulator_cpu_before = time.perf_counter(), time.process_time()
            stats = asyncio.run(watched())
            elapsed_s = time.perf_counter() - started
            cpu_used_s = cpu_s([process.pid]) - cpu_before
            loop_user_s, loop_kernel_s, work_cpu_s = np.subtract(_thread_cpu_s(process.pid), threads_before)
            waited_s = _waited_s(process.pid) - waited_before
            simulator_cpu_s = time.process_time() - simulator_cpu_before
        finally:
            evaluated, _shed, stages = _stopped(process)
    reports = len(stats.response_s)
    return {
        "terminals": terminals,
        "refused": stats.refused,
        "reports": reports,
        "reports_per_s": reports / elapsed_s,
        "evaluated": evaluated,
        "response_p50_ms": _percentile_ms(stats.response_s, 50),
        "response_p99_ms": _percentile_ms(stats.response_s, 99),
        "texts": len(stats.texts),
        "texts_by_kind": dict(Counter(text.split("，")[0].split("！")[0] for text in stats.texts)),
        "text_p50_ms": _percentile_ms(stats.text_s, 50),
        "text_p99_ms": _percentile_ms(stats.text_s, 99),
        "memory_per_terminal_kb": (peak["mb"] - idle_mb) * 1024.0 / terminals,
        "gateway_cpu_us_per_report": cpu_used_s / max(reports, 1) * 1e6,
        "gateway_cores": cpu_used_s / elapsed_s,
        "gateway_loop_cpu_us_per_report": (loop_user_s + loop_kernel_s) / max(reports, 1) * 1e6,
        "gateway_loop_kernel_us_per_report": loop_kernel_s / max(reports, 1) * 1e6,
        "gateway_work_cpu_us_per_report": work_cpu_s / max(reports, 1) * 1e6,
        "gateway_waited_per_cpu_s": waited_s / max(cpu_used_s, 1e-9),
        "simulator_cores": simulator_cpu_s / elapsed_s,
        "simulator_lag_p50_ms": _percentile_ms(lags_s, 50),
        "simulator_lag_p99_ms": _percentile_ms(lags_s, 99),
        "stages_ms": stages,
        "load_1min": os.getloadavg()[0],
        "cpus": os.cpu_count(),
    }


def run_all(terminals: int = BENCH_TERMINALS) -> dict[str, Any]:
    """One gateway under ``terminals`` at 1 Hz, and the scale-out figure."""
    return {**run(terminals), "scaleout": run_scaleout(terminals // 2)}


def run_scaleout(
    terminals: int = 1000, report_s: float = 30.0, speedups: tuple[float, ...] = SCALEOUT_SPEEDUPS
) -> dict[str, Any]:
    """Reports evaluated per second by one gateway and by two on one Redis, offered more than one can take.

    The terminals replay their tracks faster than recorded, each of ``speedups`` in turn until one
    gateway sheds at least :data:`SATURATED_SHARE` of the reports it gets: only then is its rate what
    it can take rather than what the terminals offered. Two gateways are then offered the same; where
    they shed less than that share, their rate is the least two can take, not the most. The figure is
    what the gateways evaluated per second. Beside it, the CPU each kind of process used (the gateways,
    Redis, the terminals in this process) and the best ratio the node's cores allow
    (:func:`scaleout_bound`).
    """
    used: dict[int, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        phones = [f"1390{i:07d}" for i in range(terminals)]
        add_terminals(folder / "terminals.json", "bench", [NewTerminal(p, "N", f"t{p}") for p in phones])
        redis_process, url = redis_server(folder)
        try:
            for speedup in speedups:
                tracks = city_tracks(VEHICLES, report_s * speedup)
                if not tracks:
                    raise RuntimeError(f"no vehicle of the city drove {report_s * speedup / 2:g} s for the tracks")
                one = [_gateway(folder / "terminals.json", "--state", url)]
                used[1] = _cores_used(_replaying(phones, tracks, report_s, speedup), one, redis_process.pid)
                if used[1]["shed_per_s"] >= SATURATED_SHARE * used[1]["offered_per_s"]:
                    break  # else one gateway took all it was offered: offer more
            two = [_gateway(folder / "terminals.json", "--state", url) for _ in range(2)]
            used[2] = _cores_used(_replaying(phones, tracks, report_s, speedup), two, redis_process.pid)
        finally:
            redis_process.terminate()
            redis_process.wait(timeout=30)
    return {
        "terminals": terminals,
        "speedup": speedup,
        "evaluated_per_s_1": used[1]["evaluated_per_s"],
        "evaluated_per_s_2": used[2]["evaluated_per_s"],
        "ratio": used[2]["evaluated_per_s"] / used[1]["evaluated_per_s"],
        "bound": scaleout_bound(used[1], used[2], os.cpu_count() or 1),
        "gateway_ms_per_report_1": used[1]["gateway_cores"] / used[1]["evaluated_per_s"] * 1000.0,
        "gateway_ms_per_report_2": used[2]["gateway_cores"] / used[2]["evaluated_per_s"] * 1000.0,
        "one": used[1],
        "two": used[2],
        "load_1min": os.getloadavg()[0],
    }


def _replaying(
    phones: list[str], tracks: list[Track], report_s: float, speedup: float
) -> list[tuple[SimulatedTerminal, int]]:
    """A terminal for each of ``phones``, numbered, replaying the first ``report_s * speedup`` seconds of one
    of ``tracks`` in turn ``speedup`` times faster than recorded."""
    return [
        (SimulatedTerminal(phone, _faster(_cut(tracks[i % len(tracks)], report_s * speedup), speedup)), i)
        for i, phone in enumerate(phones)
    ]


def _cores_used(
    simulated: list[tuple[SimulatedTerminal, int]], gateways: list[tuple[subprocess.Popen, int]], redis_pid: int
) -> dict[str, float]:
    """Run the terminals against ``gateways``, stop them; the reports evaluated per second and the cores each
    kind of process used meanwhile (CPU seconds per second of the run)."""
    pids = [process.pid for process, _ in gateways]
    before = (cpu_s(pids), cpu_s([redis_pid]), time.process_time(), time.perf_counter())
    asyncio.run(_split(simulated, [port for _, port in gateways]))
    after = (cpu_s(pids), cpu_s([redis_pid]), time.process_time(), time.perf_counter())
    elapsed_s = after[3] - before[3]
    stopped = [_stopped(process) for process, _ in gateways]
    evaluated, shed = sum(counts[0] for counts in stopped), sum(counts[1] for counts in stopped)
    return {
        "evaluated_per_s": evaluated / elapsed_s,
        "shed_per_s": shed / elapsed_s,
        "offered_per_s": (evaluated + shed) / elapsed_s,
        "gateway_cores": (after[0] - before[0]) / elapsed_s,
        "redis_cores": (after[1] - before[1]) / elapsed_s,
        "simulator_cores": (after[2] - before[2]) / elapsed_s,
    }


def scaleout_bound(one: dict[str, float], two: dict[str, float], cores: int) -> float:
    """The best ratio two gateways can reach over one on ``cores`` shared with the terminals and Redis.

    Each report evaluated costs the gateways ``g`` and Redis ``r`` CPU seconds (as measured with one
    gateway); the terminals take ``s`` cores whatever the gateways do (they offer the same reports).
    Two gateways then evaluate at most ``(cores - s) / (g + r)`` reports per second, and at most
    twice what one did alone (each gateway's evaluation is one thread); over one gateway's rate:
    ``min(2, (cores - s) / ((g + r) * rate_1))``. Other work on the node lowers it further.
    """
    rate = one["evaluated_per_s"]
    per_report_s = (one["gateway_cores"] + one["redis_cores"]) / rate
    simulator_cores = max(one["simulator_cores"], two["simulator_cores"])
    return min(2.0, (cores - simulator_cores) / (per_report_s * rate))


async def _split(simulated: list[tuple[SimulatedTerminal, int]], ports: list[int]) -> None:
    """Each terminal to the gateway its number picks, all at once."""
    await asyncio.gather(
        *(simulate([t for t, i in simulated if i % len(ports) == k], "127.0.0.1", port) for k, port in enumerate(ports))
    )


def _faster(track: Track, speedup: float) -> Track:
    """``track`` replayed ``speedup`` times faster."""
    return Track(track.time_s / speedup, track.lon_deg, track.lat_deg, track.speed_kmh, track.heading_deg)


def _cut(track: Track, report_s: float) -> Track:
    """The first ``report_s`` seconds of ``track``."""
    keep = track.time_s < report_s
    return Track(
        *(column[keep] for column in (track.time_s, track.lon_deg, track.lat_deg, track.speed_kmh, track.heading_deg))
    )


def rows(figures: dict[str, Any]) -> list[Row]:
    """The benchmark table's rows of :func:`run`'s figures."""
    size = f"{figures['terminals']:,} terminals at 1 Hz, {figures['reports_per_s']:.0f} reports/s"
    # A text does not name its report: the terminals time it from their latest one, which understates
    # beyond the reporting interval; the gateway's own read-to-written time does not.
    text_p99_ms = max(figures["text_p99_ms"], figures["stages_ms"].get("text", (0.0, 0.0))[1])
    return [
        at_most(
            "jt808: report to 0x8300 p99, ms",
            text_p99_ms,
            TARGET_P99_MS,
            f"{figures['texts']} texts; {size}; the terminals' or the gateway's own, the longer",
        ),
        context(
            "jt808: report read to 0x8300 written inside the gateway p50 / p99, ms",
            "{:.1f} / {:.1f}".format(*figures["stages_ms"].get("text", (math.nan, math.nan))),
            "gateway loop lag p99 {:.1f} ms, terminals' {:.1f} ms; load {:.1f} on {} cores".format(
                figures["stages_ms"].get("loop_lag", (math.nan, math.nan))[1],
                figures["simulator_lag_p99_ms"],
                figures["load_1min"],
                figures["cpus"],
            ),
        ),
        context(
            "jt808: report to 0x8001 p50 / p99, ms",
            f"{figures['response_p50_ms']:.1f} / {figures['response_p99_ms']:.1f}",
        ),
        at_most("jt808: terminals refused", figures["refused"], 0),
        at_least(
            "jt808: terminals at 1 Hz on one node",
            figures["terminals"] if text_p99_ms <= TARGET_P99_MS else 0,
            TARGET_TERMINALS,
            f"{figures['terminals']:,} run, counted if their p99 met the target",
        ),
        context("jt808: gateway CPU per report, µs", figures["gateway_cpu_us_per_report"], size),
        context(
            f"jt808: cores {TARGET_TERMINALS:,} terminals at 1 Hz take in gateways",
            TARGET_TERMINALS * figures["gateway_cpu_us_per_report"] / 1e6,
            "at the CPU per report measured; one gateway process gets at most one core",
        ),
        context("jt808: gateway memory per terminal, KB", figures["memory_per_terminal_kb"]),
        *_scaleout_rows(figures["scaleout"]),
    ]


def _scaleout_rows(scaleout: dict[str, Any]) -> list[Row]:
    """The scale-out rows: the measured ratio and, beside it, the best the node's cores allow."""
    one, two = scaleout["one"], scaleout["two"]
    saturated = [_share(used) >= SATURATED_SHARE for used in (one, two)]
    reading = {
        (True, True): "both saturated",
        (True, False): "two took all they got: the least two can take",
        (False, True): "one gateway not saturated: not a capacity ratio",
        (False, False): "neither saturated: not a capacity ratio",
    }[saturated[0], saturated[1]]
    return [
        at_least(
            "jt808: reports evaluated, 2 gateways on one Redis / 1",
            scaleout["ratio"],
            TARGET_SCALEOUT,
            f"{scaleout['evaluated_per_s_2']:.0f} vs {scaleout['evaluated_per_s_1']:.0f} reports/s, "
            f"{scaleout['terminals']:,} terminals at {scaleout['speedup']:g} times their pace; "
            f"shed {_share(one):.0%} by one gateway, {_share(two):.0%} by two ({reading}); "
            f"best the cores allow {scaleout['bound']:.2f}",
        ),
        context(
            "jt808: best 2-gateway ratio the node's cores allow",
            scaleout["bound"],
            f"the terminals take {two['simulator_cores']:.2f} cores and send {two['offered_per_s']:.0f} reports/s, "
            f"Redis {two['redis_cores']:.2f}, the gateways {two['gateway_cores']:.2f} "
            f"(load {scaleout['load_1min']:.1f})",
        ),
        context(
            "jt808: gateway CPU per report, 1 gateway / 2, ms",
            f"{scaleout['gateway_ms_per_report_1']:.3f} / {scaleout['gateway_ms_per_report_2']:.3f}",
            f"the gateways ran on {scaleout['one']['gateway_cores']:.2f} then {two['gateway_cores']:.2f} cores",
        ),
    ]


def _share(used: dict[str, float]) -> float:
    """The share of the reports they got that the gateways shed."""
    return used["shed_per_s"] / used["offered_per_s"] if used["offered_per_s"] else 0.0


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.jt808 [TERMINALS] [--scaleout-only | --single] [--report-s S] [--loop L] [--profile F]``:
    print the figures."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.jt808", description=__doc__.split("\n\n")[0])
    parser.add_argument("terminals", type=int, nargs="?", default=BENCH_TERMINALS, help="terminals at 1 Hz")
    parser.add_argument(
        "--scaleout-only",
        action="store_true",
        help="only one gateway against two on one Redis, with TERMINALS terminals (a small run: 300)",
    )
    parser.add_argument(
        "--report-s", type=float, default=None, help="how long the terminals report, s (scale-out 30, one gateway 60)"
    )
    parser.add_argument("--single", action="store_true", help="only one gateway under TERMINALS, no scale-out")
    parser.add_argument("--loop", default="auto", help="the gateway's event loop: auto, uvloop or asyncio")
    parser.add_argument("--profile", default=None, metavar="FILE", help="the gateway's cProfile of its event loop")
    parser.add_argument(
        "--group-sizes", action="store_true", help="only the CPU per report of a group's evaluation by group size"
    )
    args = parser.parse_args(argv)
    if args.group_sizes:
        from benchmarks.jt808_groups import run_group_sizes  # it builds on this module

        figures = run_group_sizes()
    elif args.scaleout_only:
        figures = run_scaleout(args.terminals, args.report_s or 30.0)
    elif args.single:
        options = ["--loop", args.loop, *(["--profile", str(Path(args.profile).resolve())] if args.profile else [])]
        figures = run(args.terminals, args.report_s or REPORT_S, *options)
    else:
        figures = run_all(args.terminals)
    for name, value in figures.items():
        print(f"{name}: {value:.4g}" if isinstance(value, float) else f"{name}: {value}")


if __name__ == "__main__":
    main()
