"""``csws sweep`` on Dask: the speed-up of two local workers over one, and Dask's cost per task.

Eight short runs (the bundled fleet, ``VEHICLES`` vehicles, ``END_S`` simulated seconds, all
vehicles equipped, seeds 0-7) are timed three ways, each whole, results written as a sweep
writes them:

* ``loop``: :func:`csws.sweep.task.run_task` eight times in this process, one after another;
* ``1 worker`` and ``2 workers``: :func:`csws.sweep.execute.run_sweep` on a LocalCluster of
  that many worker processes (one thread each), started and warmed (one run each, so the
  imports and the network's first load are not timed) before the clock starts.

Targets: two workers at least 1.8 times as fast as one (on two cores), and one worker at
most 5 % slower than the plain loop (Dask's per-task overhead: scheduling, sending the task
and its result, writing the result file).

Run with ``python -m benchmarks.sweep``.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from benchmarks.command import arguments
from csws.sweep.execute import run_sweep
from csws.sweep.study import Factors, RunSpec, ScenarioSpec
from csws.sweep.task import run_task

RUNS = 8
VEHICLES = 120
END_S = 180.0
TARGET_SPEEDUP = 1.8
TARGET_OVERHEAD_PERCENT = 5.0


def _runs(seeds: range) -> list[RunSpec]:
    """The benchmark's runs: one setting, one run per seed."""
    scenario = ScenarioSpec("fleet", None, VEHICLES, END_S)
    return [RunSpec(scenario, Factors(1.0, 1.0, 0.8, 4.9, 0.1, "scenario"), seed) for seed in seeds]


def _on_cluster(workers: int, runs: list[RunSpec]) -> float:
    """Seconds the sweep of ``runs`` takes on a warmed LocalCluster of ``workers`` processes."""
    from dask.distributed import Client, LocalCluster

    warm_up = _runs(range(1000, 1000 + workers))
    with (
        LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster,
        Client(cluster) as client,
        tempfile.TemporaryDirectory() as folder,
    ):
        client.gather(client.map(run_task, warm_up, pure=False))
        started = time.perf_counter()
        report = run_sweep(runs, Path(folder), scheduler=cluster.scheduler_address, progress=False)
        elapsed = time.perf_counter() - started
    if report.failed or len(report.ran) != len(runs):
        raise RuntimeError(f"the sweep on {workers} worker(s) did not run every run: {report.failed}")
    return elapsed


def run() -> dict:
    """Time the loop, one worker and two workers; the figures."""
    runs = _runs(range(RUNS))
    run_task(_runs(range(999, 1000))[0])  # warm: imports and the network's first load
    started = time.perf_counter()
    for spec in runs:
        run_task(spec)
    loop_s = time.perf_counter() - started
    one_s = _on_cluster(1, runs)
    two_s = _on_cluster(2, runs)
    return {
        "runs": RUNS,
        "cores": os.cpu_count(),
        "loop_s": round(loop_s, 2),
        "one_worker_s": round(one_s, 2),
        "two_workers_s": round(two_s, 2),
        "speedup": round(one_s / two_s, 2),
        "overhead_percent": round(100.0 * (one_s - loop_s) / loop_s, 1),
        "overhead_ms_per_task": round(1000.0 * (one_s - loop_s) / RUNS, 1),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }


if __name__ == "__main__":
    arguments("benchmarks.sweep", __doc__)
    print(run())
