"""A study's runs on Dask: one task per run, each result written the moment it arrives.

By default the runs go to a :class:`dask.distributed.LocalCluster` of one worker process per
core, one thread each: libsumo holds one simulation per process, and a process per run keeps
the runs apart (a run that crashes SUMO takes one worker down, which the nanny restarts).
``scheduler="tcp://HOST:PORT"`` uses a running cluster instead (``dask scheduler`` and
``dask worker --nthreads 1`` on each machine; every worker needs csws installed and the
scenario's files at the same path).

What survives what:

* each finished run's row is written to ``DIR/runs/KEY.parquet`` at once, by this process
  (:mod:`csws.sweep.results`), so workers need no shared disk;
* runs whose file exists are not submitted again: a killed sweep resumes where it stopped;
* a worker that dies mid-run loses its task to the scheduler, which runs it again on another
  worker (up to ``distributed.scheduler.allowed-failures`` times); each task is one future
  with the run's key, so its result arrives once and is written once;
* every run is seeded (SUMO, the generated fleet, who is equipped and complies) and runs
  alone in its process, so its row is the same on any worker and with any number of them.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from csws.cli.progress import Progress

from .results import result_path, write_result
from .study import RunSpec
from .task import run_task

__all__ = ["SweepReport", "run_sweep", "dask_client", "LOG_NAME"]

#: Each run's end, one line each, in the output folder.
LOG_NAME = "sweep.log"


@dataclass
class SweepReport:
    """What a sweep did: the keys of runs done before, run now, and failed (with the error)."""

    total: int
    done_before: list[str] = field(default_factory=list)
    ran: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)


@contextmanager
def dask_client(scheduler: str | None, workers: int | None, stream: TextIO) -> Iterator:
    """A Dask client: of the cluster at ``scheduler``, or of a new local cluster of ``workers``
    processes with one thread each (default: one per core). Prints the dashboard's address.

    Raises
    ------
    ValueError
        When the scheduler cannot be reached.
    """
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise ValueError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        cluster = None
    else:
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True)
        client = Client(cluster)
    try:
        if "dashboard" in client.scheduler_info().get("services", {}):
            print(f"csws sweep: Dask dashboard at {client.dashboard_link}", file=stream, flush=True)
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_sweep(
    runs: list[RunSpec],
    out: Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    stream: TextIO | None = None,
) -> SweepReport:
    """Run every run of ``runs`` whose result is not in ``out`` yet, on Dask; write each result at once.

    Parameters
    ----------
    runs
        The study's runs (:meth:`csws.sweep.study.Study.runs`).
    out
        The output folder: ``runs/KEY.parquet`` per run, ``sweep.log``.
    scheduler
        ``tcp://HOST:PORT`` of a running Dask scheduler; None starts a local cluster.
    workers
        Worker processes of the local cluster (default: one per core).
    progress
        Show runs done of all and the time left on ``stream`` (stderr).
    """
    stream = sys.stderr if stream is None else stream
    done = {spec.key for spec in runs if result_path(out, spec.key).is_file()}
    report = SweepReport(total=len(runs), done_before=sorted(done))
    pending = [spec for spec in runs if spec.key not in done]
    if not pending:
        return report
    out.mkdir(parents=True, exist_ok=True)
    with dask_client(scheduler, workers, stream) as client, open(out / LOG_NAME, "a", encoding="utf-8") as log:
        from dask.distributed import as_completed

        bar = Progress(
            "sweep", len(runs), "runs", enabled=progress, stream=stream, done=len(report.done_before), time_left=True
        )
        futures = client.map(run_task, pending, key=[f"csws-run-{spec.key}" for spec in pending])
        key_of = {future.key: spec.key for future, spec in zip(futures, pending, strict=False)}
        try:
            for future in as_completed(futures):
                key = key_of[future.key]
                try:
                    write_result(out, future.result())
                    report.ran.append(key)
                    _log(log, f"run {key} done")
                except Exception as exc:  # noqa: BLE001 - a failed run is reported; the others go on
                    report.failed[key] = " ".join(f"{type(exc).__name__}: {exc}".split())
                    _log(log, f"run {key} failed: {report.failed[key]}")
                future.release()
                bar.update()
        finally:
            bar.close()
    return report


def _log(log: TextIO, text: str) -> None:
    """One line of the sweep's log, with the time."""
    log.write(f"{time.strftime('%Y-%m-%dT%H:%M:%S')} {text}\n")
    log.flush()
