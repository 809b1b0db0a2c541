"""Prometheus metrics of the service: requests, latencies and warnings by level, summed over the workers.

A small text-format exposition (version 0.0.4) with no dependency: counters of
requests by route and status, a latency histogram by route, and counters of the
answers by system state and warning level, and of the queries of batches not answered.
:class:`MetricsMiddleware` is a plain ASGI middleware, so measuring costs next to nothing per
request; it also writes the access log (:mod:`service.access_log`).

The workers of ``csws serve --workers N`` each count their own requests. Each writes its
counters, when they changed, at most once per :data:`SHARE_PERIOD_S` to a file of its own in a
folder the master made (:data:`METRICS_DIR_VARIABLE`), and ``/metrics`` answers the sum of its
own live counters and the other workers' files (those of workers that died included, so that the
counters never go down): Prometheus' multiprocess mode, without its files per metric. A request
pays nothing for it; the sum lags up to a period behind the other workers.
"""

from __future__ import annotations

import asyncio
import bisect
import json
import logging
import os
import time
from collections import Counter, defaultdict
from collections.abc import Iterable
from itertools import accumulate
from pathlib import Path
from typing import Any

from .access_log import AccessLog

__all__ = ["LATENCY_BUCKETS_S", "METRICS_DIR_VARIABLE", "SHARE_PERIOD_S", "Metrics", "MetricsMiddleware"]

#: Upper bounds of the latency histogram's buckets, s.
LATENCY_BUCKETS_S = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)
logger = logging.getLogger("csws.service")

#: Set by ``csws serve --workers N`` for its workers: the folder where each keeps its counters.
METRICS_DIR_VARIABLE = "CSWS_METRICS_DIR"
#: How often a worker writes its counters to that folder when they changed, s.
SHARE_PERIOD_S = 1.0


def _labels(**labels: Any) -> str:
    return ",".join(f'{name}="{str(value)}"' for name, value in labels.items())


class Metrics:
    """The counters and histograms, and their exposition.

    Attributes
    ----------
    access_log
        Where each request is logged, if anywhere (``csws serve --access-log``).
    changed
        Whether anything was counted since the counters were last shared with the other workers.
    """

    def __init__(self) -> None:
        self.access_log: AccessLog | None = None
        self.changed = False
        self.requests: dict[tuple[str, str, int], int] = defaultdict(int)
        #: Per route, the requests of each latency bucket alone (the last: above every bound);
        #: the exposition adds them up into Prometheus' cumulative buckets.
        self.latency_buckets: dict[str, list[int]] = defaultdict(lambda: [0] * (len(LATENCY_BUCKETS_S) + 1))
        self.latency_sum_s: dict[str, float] = defaultdict(float)
        self.latency_count: dict[str, int] = defaultdict(int)
        self.answers: dict[tuple[str, int], int] = defaultdict(int)
        self.item_errors: dict[str, int] = defaultdict(int)
        #: Push (service.push): events by kind of sink and outcome, and per kind of sink the events waiting
        #: and the lag of the last delivery, s (a dispatcher without the lease reports zeros).
        self.push_events: dict[tuple[str, str], int] = defaultdict(int)
        self.push_gauges: dict[str, tuple[int, float]] = {}

    def observe_request(self, method: str, route: str, status: int, seconds: float) -> None:
        """Count a request and its latency."""
        self.changed = True
        self.requests[(method, route, status)] += 1
        self.latency_buckets[route][bisect.bisect_left(LATENCY_BUCKETS_S, seconds)] += 1
        self.latency_sum_s[route] += seconds
        self.latency_count[route] += 1

    def observe_answers(self, states: Iterable[str], levels: Iterable[int]) -> None:
        """Count answers by system state and warning level (parallel sequences)."""
        for key, count in Counter(zip(states, levels, strict=False)).items():
            self.answers[key] += count

    def observe_item_errors(self, codes: Iterable[str]) -> None:
        """Count the queries of batches not answered, by the code of their error entry."""
        for code, count in Counter(codes).items():
            self.item_errors[code] += count

    def observe_push(self, sink: str, outcome: str, count: int = 1) -> None:
        """Count events pushed to a kind of sink (webhook, mqtt) with an outcome (delivered, retried, dead_lettered)."""
        self.changed = True
        self.push_events[(sink, outcome)] += count

    def set_push_gauges(self, sink: str, waiting: int, lag_s: float) -> None:
        """The events waiting for a kind of sink, and the lag of its last delivery, s."""
        if self.push_gauges.get(sink) != (waiting, lag_s):
            self.changed = True
            self.push_gauges[sink] = (waiting, lag_s)

    def snapshot(self) -> dict[str, Any]:
        """The counters as JSON values, for the other workers (:meth:`add`)."""
        return {
            "requests": [[*key, count] for key, count in self.requests.items()],
            "latency": {
                route: [self.latency_buckets[route], self.latency_sum_s[route], count]
                for route, count in self.latency_count.items()
            },
            "answers": [[*key, count] for key, count in self.answers.items()],
            "item_errors": dict(self.item_errors),
            "push": [[*key, count] for key, count in list(self.push_events.items())],
            "push_gauges": {sink: list(gauges) for sink, gauges in list(self.push_gauges.items())},
        }

    def add(self, snapshot: dict[str, Any]) -> None:
        """Add the counters of a :meth:`snapshot` (another worker's) to these."""
        for method, route, status, count in snapshot["requests"]:
            self.requests[(method, route, status)] += count
        for route, (buckets, sum_s, count) in snapshot["latency"].items():
            self.latency_buckets[route] = [a + b for a, b in zip(self.latency_buckets[route], buckets, strict=True)]
            self.latency_sum_s[route] += sum_s
            self.latency_count[route] += count
        for state, level, count in snapshot["answers"]:
            self.answers[(state, level)] += count
        for code, count in snapshot["item_errors"].items():
            self.item_errors[code] += count
        for sink, outcome, count in snapshot.get("push", []):
            self.push_events[(sink, outcome)] += count
        for sink, (waiting, lag_s) in snapshot.get("push_gauges", {}).items():
            before = self.push_gauges.get(sink, (0, 0.0))
            self.push_gauges[sink] = (before[0] + waiting, before[1] + lag_s)

    def share(self, folder: Path) -> None:
        """Write the counters to this process' file in ``folder``, whole or not at all."""
        self.changed = False
        written = folder / f"{os.getpid()}.json.part"
        written.write_text(json.dumps(self.snapshot()))
        os.replace(written, folder / f"{os.getpid()}.json")

    async def keep_sharing(self, folder: Path) -> None:
        """Share the counters in ``folder`` every :data:`SHARE_PERIOD_S` in which they changed, until cancelled."""
        while True:
            await asyncio.sleep(SHARE_PERIOD_S)
            if self.changed:
                try:
                    self.share(folder)
                except OSError as error:  # a full disk, the folder gone while stopping: try again next period
                    logger.warning("the metrics cannot be shared with the other workers: %s", error)

    def summed(self) -> tuple[Metrics, int]:
        """These counters plus those the other workers shared (all of them with ``csws serve --workers N``),
        and how many processes that sums."""
        folder = _shared_folder()
        if folder is None:
            return self, 1
        total, processes = Metrics(), 1
        total.add(self.snapshot())
        own = f"{os.getpid()}.json"
        for path in folder.glob("*.json"):
            if path.name != own:
                try:
                    shared = json.loads(path.read_text())
                except (OSError, ValueError):  # the folder removed while the service stops
                    continue
                total.add(shared)
                processes += 1
        return total, processes

    def exposition(self) -> str:
        """The metrics in Prometheus' text format, summed over the workers."""
        total, processes = self.summed()
        return total.lines(processes)

    def lines(self, processes: int = 1) -> str:
        """These counters in Prometheus' text format, as the sum over ``processes`` processes."""
        lines = [
            "# HELP csws_worker_processes The processes whose counters are summed (the workers, live or not).",
            "# TYPE csws_worker_processes gauge",
            f"csws_worker_processes {processes}",
            "# HELP csws_http_requests_total HTTP requests by method, route and status.",
            "# TYPE csws_http_requests_total counter",
        ]
        for (method, route, status), count in sorted(self.requests.items()):
            lines.append(f"csws_http_requests_total{{{_labels(method=method, route=route, status=status)}}} {count}")
        lines += [
            "# HELP csws_http_request_duration_seconds Time to answer an HTTP request.",
            "# TYPE csws_http_request_duration_seconds histogram",
        ]
        for route in sorted(self.latency_count):
            below = accumulate(self.latency_buckets[route][:-1])  # the last bucket is the +Inf one, below
            for bound, count in zip(LATENCY_BUCKETS_S, below, strict=True):
                lines.append(f"csws_http_request_duration_seconds_bucket{{{_labels(route=route, le=bound)}}} {count}")
            lines.append(
                f"csws_http_request_duration_seconds_bucket{{{_labels(route=route, le='+Inf')}}} "
                f"{self.latency_count[route]}"
            )
            lines.append(
                f"csws_http_request_duration_seconds_sum{{{_labels(route=route)}}} {self.latency_sum_s[route]}"
            )
            lines.append(
                f"csws_http_request_duration_seconds_count{{{_labels(route=route)}}} {self.latency_count[route]}"
            )
        lines += [
            "# HELP csws_answers_total Answers given, by system state and warning level.",
            "# TYPE csws_answers_total counter",
        ]
        for (state, level), count in sorted(self.answers.items()):
            lines.append(f"csws_answers_total{{{_labels(state=state, level=level)}}} {count}")
        lines += [
            "# HELP csws_batch_item_errors_total Queries of batches not answered, by error code.",
            "# TYPE csws_batch_item_errors_total counter",
        ]
        for code, count in sorted(self.item_errors.items()):
            lines.append(f"csws_batch_item_errors_total{{{_labels(code=code)}}} {count}")
        return "\n".join(lines + self._push_lines()) + "\n"

    def _push_lines(self) -> list[str]:
        """The push counters and gauges in Prometheus' text format."""
        lines = [
            "# HELP csws_push_events_total Events pushed, by kind of sink and outcome (delivered, retried, "
            "dead_lettered).",
            "# TYPE csws_push_events_total counter",
        ]
        for (sink, outcome), count in sorted(self.push_events.items()):
            lines.append(f"csws_push_events_total{{{_labels(sink=sink, outcome=outcome)}}} {count}")
        for name, index, text in (
            ("csws_push_waiting_events", 0, "Events waiting for a retry, by kind of sink."),
            ("csws_push_lag_seconds", 1, "Time from an event to its delivery, the last one, by kind of sink."),
        ):
            lines += [f"# HELP {name} {text}", f"# TYPE {name} gauge"]
            lines += [
                f"{name}{{{_labels(sink=sink)}}} {gauges[index]}" for sink, gauges in sorted(self.push_gauges.items())
            ]
        return lines


def _shared_folder() -> Path | None:
    """The folder the workers share their counters in, None outside ``csws serve --workers N``."""
    folder = os.environ.get(METRICS_DIR_VARIABLE)
    return Path(folder) if folder else None


#: The HTTP methods counted under their own name.
METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "DELETE", "PATCH", "OPTIONS"})


class MetricsMiddleware:
    """ASGI middleware that counts every HTTP request and times it.

    Requests are labelled by their route template (``/v1/vehicles/{vehicle_id}``), not
    the raw path, and by their method, any but the standard ones (:data:`METHODS`) as
    ``other``, so the number of series stays bounded whatever clients send.
    """

    def __init__(self, app, metrics: Metrics) -> None:
        self.app = app
        self.metrics = metrics
        self.sharing: asyncio.Task | None = None

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if self.sharing is None:
            self.sharing = self._start_sharing()
        started = time.perf_counter()
        status = 500

        async def send_with_status(message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, send_with_status)
        finally:
            route = scope.get("route")
            template = getattr(route, "path", None) or "unmatched"
            method = scope["method"] if scope["method"] in METHODS else "other"
            seconds = time.perf_counter() - started
            self.metrics.observe_request(method, template, status, seconds)
            if self.metrics.access_log is not None:
                self.metrics.access_log.record(scope, status, seconds)

    def _start_sharing(self) -> asyncio.Task:
        """In a worker of ``csws serve --workers N``, on its first request: the task that shares its counters
        (:meth:`Metrics.keep_sharing`); elsewhere a task that is done at once."""
        folder = _shared_folder()
        if folder is None:
            return asyncio.get_running_loop().create_task(asyncio.sleep(0))
        return asyncio.get_running_loop().create_task(self.metrics.keep_sharing(folder))
