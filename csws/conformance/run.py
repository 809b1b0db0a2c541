"""``csws conformance``: run the rows of 7.5 in SUMO, judge them (7.6) and write the report.

Each row runs on each of its tracks at each step length as one task (one SUMO simulation
with the row's repetitions). Tasks run in worker processes (``--jobs``; libsumo holds one
simulation per process) started with ``spawn``; each worker judges its runs and sends back
the results and the records the plots need.
"""

from __future__ import annotations

import argparse
import fnmatch
import multiprocessing
import time
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from csws.cli.progress import Progress

from .drive import Task, Trace, Truth, drive, truth
from .judge import CONSECUTIVE_PASSES, RunResult, consecutive_passes, judge_run
from .realroads import REAL_ROAD_TABLE, judge_real_road_run, real_road_rows
from .report import CswsOutcome, GroupOutcome, RowOutcome, plot_row, verdicts, write_json, write_markdown
from .rows import Row, procedure_rows

__all__ = ["DEFAULT_STEP_LENGTHS_S", "select_rows", "make_tasks", "run_task", "run_tasks", "conformance", "main"]

#: The step lengths the procedure must pass at, s.
DEFAULT_STEP_LENGTHS_S = (0.01, 0.05, 0.1, 0.2)

TaskResult = tuple[Task, tuple[RunResult, ...], tuple[Trace, ...]]


def select_rows(
    tables: Sequence[int] | None = None, categories: Sequence[str] | None = None, patterns: Sequence[str] | None = None
) -> list[Row]:
    """The rows of the procedure and the real-road rows, filtered by table (0 = negative rows,
    10 = real-road tracks), category and row-id pattern."""
    rows = procedure_rows() + real_road_rows()
    if tables:
        rows = [r for r in rows if r.table in tables]
    if categories:
        wanted = {c.upper() for c in categories}
        rows = [r for r in rows if r.category.value in wanted]
    if patterns:
        rows = [r for r in rows if any(fnmatch.fnmatchcase(r.row_id, p) for p in patterns)]
    if not rows:
        raise ValueError("no row of the procedure matches the selection")
    return rows


def make_tasks(
    rows: Iterable[Row],
    step_lengths_s: Sequence[float],
    repetitions: int,
    seed: int,
    directions: Sequence[str] | None = None,
) -> list[Task]:
    """One task per row, track and step length; ``directions`` keeps only the standard's tracks ending in
    those (left, right, s), and every real-road track."""
    if repetitions < CONSECUTIVE_PASSES:
        raise ValueError(f"at least {CONSECUTIVE_PASSES} repetitions are needed (7.5.1), got {repetitions}")
    tasks = [
        Task(row, track, step, repetitions, seed)
        for row in rows
        for track in row.tracks
        if not directions or row.table == REAL_ROAD_TABLE or track.rsplit("_", 1)[-1] in directions
        for step in step_lengths_s
    ]
    if not tasks:
        raise ValueError("no track of the selected rows has the selected directions")
    # Longest first, so that the workers finish together.
    return sorted(tasks, key=lambda t: t.step_length_s)


def run_task(task: Task) -> TaskResult:
    """Drive and judge one task (in a worker process)."""
    traces = tuple(drive(task))
    track_truth = truth(task.track)
    judge = judge_real_road_run if task.row.table == REAL_ROAD_TABLE else judge_run
    return task, tuple(judge(task.row, trace, track_truth) for trace in traces), traces


def run_tasks(
    tasks: Sequence[Any], jobs: int, progress: bool = False, worker: Callable[[Any], Any] = run_task
) -> Iterator[Any]:
    """Run the tasks through ``worker`` (a module-level function), in this process for one job, else
    in ``jobs`` spawned worker processes; with ``progress``, show how far they are
    (:class:`csws.cli.progress.Progress`)."""
    bar = Progress("conformance", len(tasks), "tasks", enabled=progress)
    try:
        if jobs <= 1:
            for task in tasks:
                yield worker(task)
                bar.update()
            return
        with ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
            for result in pool.map(worker, tasks, chunksize=1):
                yield result
                bar.update()
    finally:
        bar.close()


def _outcomes(
    results: Iterable[TaskResult], rows: Sequence[Row]
) -> tuple[list[CswsOutcome], dict[str, list[tuple[Truth, float, Trace]]]]:
    """Row outcomes (without plots) from task results, and each row's runs for its plot."""
    groups: dict[str, list[GroupOutcome[RunResult]]] = defaultdict(list)
    records: dict[str, list[tuple[Truth, float, Trace]]] = defaultdict(list)
    for task, runs, traces in results:
        passed = consecutive_passes(runs)
        groups[task.row.row_id].append(GroupOutcome(task.track, task.step_length_s, runs, passed))
        records[task.row.row_id] += [(truth(task.track), task.step_length_s, trace) for trace in traces]
    outcomes = [
        RowOutcome(row, tuple(sorted(groups[row.row_id], key=lambda g: (g.track, g.step_length_s))), None)
        for row in rows
        if row.row_id in groups
    ]
    return outcomes, records


def conformance(
    rows: Sequence[Row],
    out: Path,
    step_lengths_s: Sequence[float] = DEFAULT_STEP_LENGTHS_S,
    repetitions: int = CONSECUTIVE_PASSES,
    seed: int = 0,
    jobs: int = 1,
    plots: bool = True,
    directions: Sequence[str] | None = None,
    progress: bool = False,
) -> list[CswsOutcome]:
    """Run, judge and report the rows; the outcomes, one per row.

    Writes ``report.json``, ``report.md`` and (with ``plots``) ``plots/ROW.png`` into ``out``.
    """
    tasks = make_tasks(rows, step_lengths_s, repetitions, seed, directions)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    outcomes, records = _outcomes(run_tasks(tasks, jobs, progress), rows)
    elapsed_s = time.perf_counter() - started
    if plots:
        (out / "plots").mkdir(exist_ok=True)
        for index, outcome in enumerate(outcomes):
            name = f"plots/{outcome.row.row_id}.png"
            plot_row(out / name, outcome.row, records[outcome.row.row_id])
            outcomes[index] = RowOutcome(outcome.row, outcome.groups, name)
    settings = {
        "step_lengths_s": list(step_lengths_s),
        "repetitions": repetitions,
        "seed": seed,
        "jobs": jobs,
        "directions": list(directions) if directions else None,
        "tasks": len(tasks),
        "simulation_wall_time_s": round(elapsed_s, 3),
    }
    write_json(out / "report.json", outcomes, settings)
    write_markdown(out / "report.md", outcomes, settings)
    return outcomes


def main(args: argparse.Namespace) -> int:
    """The ``csws conformance`` command: exit 0 when every row passes, 1 when one fails."""
    if args.system == "fcw":
        from .fcw.run import main as fcw_main

        return fcw_main(args)
    rows = select_rows(args.tables, args.categories, args.rows)
    started = time.perf_counter()
    outcomes = conformance(
        rows,
        args.out,
        args.step_lengths,
        args.repetitions,
        args.seed,
        args.jobs,
        plots=not args.no_plots,
        directions=args.directions,
        progress=True,
    )
    verdict = verdicts(outcomes)
    for outcome in outcomes:
        if not outcome.passed:
            print(f"FAIL {outcome.row.row_id}")
    said = {True: "PASS", False: "FAIL", None: "not run"}
    print(
        f"7.6: {said[verdict['clause_7_6_passed']]}; negative rows: {said[verdict['negative_rows_passed']]}; "
        f"real-road tracks: {said[verdict['real_road_tracks_passed']]}; "
        f"{len(outcomes)} rows, {len(verdict['rows_failed'])} failed, "
        f"in {time.perf_counter() - started:.1f} s; report: {args.out / 'report.md'}"
    )
    return 1 if verdict["rows_failed"] else 0
