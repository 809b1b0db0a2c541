"""What a group of reports costs the JT/T 808 gateway: CPU per report by group size, and its fixed part.

``python -m benchmarks.jt808 --group-sizes`` runs :func:`run_group_sizes`: the same reports of the
bundled city's SUMO tracks answered in groups of 8 to 256 through the gateway's group step on Redis,
timed by the work thread's CPU.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any, cast

import numpy as np

from benchmarks.jt808 import NET, VEHICLES, city_tracks
from benchmarks.servers import redis_server
from csws.gateways.jt808.messages import STATUS_POSITIONED, LocationReport
from csws.gateways.jt808.simulator import Track
from csws.gateways.jt808.terminals import Terminal
from csws.gateways.jt808.tracking import TrackingSettings
from csws.standard import Category
from service.timing import Stages

__all__ = ["GROUP_ROUNDS", "GROUP_SIZES", "run_group_sizes"]


#: Group sizes at which a group's evaluation is timed (``--group-sizes``), and how many rounds of reports each.
GROUP_SIZES, GROUP_ROUNDS = (256, 128, 64, 32, 16, 8), 30
#: The reports' clock of the first pass, POSIX s.
T0_S = 1_790_000_000.0


def run_group_sizes(sizes: tuple[int, ...] = GROUP_SIZES, vehicles: int = 256) -> dict[str, Any]:
    """CPU per report of a group's evaluation on the work thread at each group size, and its fit.

    ``vehicles`` terminals' reports along SUMO tracks of the bundled city are answered in groups of
    each size, as a gateway answers them (:meth:`service.jt808_groups.Batcher.answer_group` around
    :meth:`service.answers.WarningService.answer`: the state store's read, matching, engine, encoding
    and write, on Redis). Timed by the thread's CPU time, which the node's other work barely moves
    (Redis's own CPU is not in it). The fit ``c(n) = marginal + fixed / n`` gives what a group costs
    whatever its size and what each report adds: two gateways sharing the reports form groups half
    as large, so each pays ``fixed`` twice as often per report. ``gateway_ms_per_group`` is the
    fixed part of what the gateway's group step adds around the warning service.
    """
    from service.app import create_app
    from service.jt808_groups import Batcher
    from service.jt808_messages import report_query
    from service.jt808_tracking import TrackingPlanner
    from service.settings import ServiceSettings

    tracks = city_tracks(VEHICLES, GROUP_ROUNDS + 10.0)
    terminals = [Terminal(f"1{i:010d}", "bench", f"v{i}", Category.N, "", 1) for i in range(vehicles)]
    with tempfile.TemporaryDirectory() as temporary:
        redis_process, url = redis_server(Path(temporary))
        app = create_app(ServiceSettings(nets=[NET], state=url))
        service = _CpuCounted(app.state.service)
        planner = TrackingPlanner(app.state.service, TrackingSettings())
        batcher = Batcher(cast(Any, service), app.state.work, planner=planner)  # its answer() counted
        try:
            costs = {size: _group_cpu_us(batcher, service, terminals, tracks, size, T0_S + 1e4 * k, report_query)
                     for k, size in enumerate((sizes[0], *sizes))}  # fmt: skip
        finally:
            app.state.work.close()
            app.state.store.close()
            redis_process.terminate()
            redis_process.wait(timeout=30)
    # The first size's first pass warmed the caches up; its figures are those of the second.
    per_report_us = [costs[size][0] for size in sizes]
    inverse = 1.0 / np.array(sizes, dtype=float)
    fixed_us, marginal_us = np.polyfit(inverse, per_report_us, 1)
    stages = {name: float(np.polyfit(inverse, [costs[size][1].get(name, 0.0) for size in sizes], 1)[0]) / 1000.0
              for name in costs[sizes[0]][1]}  # fmt: skip
    gateway_fixed_us, _ = np.polyfit(inverse, [costs[size][2] for size in sizes], 1)
    return {
        "sizes": list(sizes),
        "cpu_us_per_report": [round(cost, 1) for cost in per_report_us],
        "fixed_ms_per_group": float(fixed_us) / 1000.0,
        "marginal_us_per_report": float(marginal_us),
        "fixed_ms_per_group_by_stage": {name: round(ms, 2) for name, ms in stages.items()},
        "gateway_ms_per_group": round(float(gateway_fixed_us) / 1000.0, 3),
        "load_1min": os.getloadavg()[0],
    }


class _CpuStages(Stages):
    """The stages of the warning service timed by the thread's CPU time, not the wall clock."""

    def __call__(self, name: str) -> AbstractContextManager:
        return _CpuStage(self, name)


class _CpuStage(AbstractContextManager):
    def __init__(self, stages: Stages, name: str) -> None:
        self.stages, self.name = stages, name

    def __enter__(self) -> _CpuStage:
        self.started = time.thread_time()
        return self

    def __exit__(self, *_exc: object) -> None:
        spent_ms = (time.thread_time() - self.started) * 1000.0
        self.stages.milliseconds[self.name] = self.stages.milliseconds.get(self.name, 0.0) + spent_ms


class _CpuCounted:
    """A warning service whose :meth:`answer` counts the thread CPU seconds spent in it (``cpu_s``)."""

    def __init__(self, service: Any) -> None:
        self.service, self.cpu_s = service, 0.0

    def answer(self, *args: Any, **kwargs: Any) -> Any:
        started = time.thread_time()
        try:
            return self.service.answer(*args, **kwargs)
        finally:
            self.cpu_s += time.thread_time() - started


def _group_cpu_us(
    batcher: Any,
    service: _CpuCounted,
    terminals: list[Terminal],
    tracks: list[Track],
    size: int,
    t0_s: float,
    query: Callable[..., Any],
) -> tuple[float, dict[str, float], float]:
    """Thread CPU µs per report of the gateway's group step on the terminals' reports in groups of ``size``, round
    after round (a later pass starts hours after the one before, so no vehicle's session carries over between
    sizes): in all, by stage of the warning service, and what the step adds around the service."""
    cpu_s, reports, stages, service.cpu_s = 0.0, 0, _CpuStages(), 0.0
    for step in range(GROUP_ROUNDS):
        for start in range(0, len(terminals), size):
            queries = []
            for number in range(start, min(start + size, len(terminals))):
                track = tracks[number % len(tracks)]
                row = min(step, len(track.time_s) - 1)
                fix = (float(track.lat_deg[row]), float(track.lon_deg[row]), 0, float(track.speed_kmh[row]))
                report = LocationReport(0, STATUS_POSITIONED, *fix, int(track.heading_deg[row]) % 360, t0_s + step)
                queries.append(query(terminals[number], report, t0_s + step))
            started = time.thread_time()
            batcher.answer_group([(q, "bench", None) for q in queries], stages)
            cpu_s += time.thread_time() - started
            reports += len(queries)
    by_stage = {name: ms / reports * 1000.0 for name, ms in stages.milliseconds.items()}
    return cpu_s / reports * 1e6, by_stage, (cpu_s - service.cpu_s) / reports * 1e6
