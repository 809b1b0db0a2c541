"""``csws conformance --system fcw``: run the FCW rows in SUMO, judge them, write the report.

One task per row and step length (its repetitions run one after another, one SUMO
simulation each); tasks run in worker processes as the CSWS suite's do
(:func:`csws.conformance.run.run_tasks`), and the outcomes are the CSWS suite's
:class:`~csws.conformance.report.GroupOutcome` and :class:`~csws.conformance.report.RowOutcome`.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import time
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from ..report import GroupOutcome, RowOutcome, mark, step_colours, verdict_text
from ..run import DEFAULT_STEP_LENGTHS_S, run_tasks
from .drive import Task, Trace, drive
from .judge import FcwRunResult, criterion, group_passes, judge_fcw_run, warning_margin_s
from .rows import FcwRow, fcw_rows

__all__ = ["select_fcw_rows", "run_fcw_task", "fcw_conformance", "main"]

TaskResult = tuple[Task, tuple[FcwRunResult, ...], tuple[Trace, ...]]
#: An FCW row with its runs.
FcwOutcome = RowOutcome[FcwRow, FcwRunResult]


def select_fcw_rows(patterns: Sequence[str] | None = None) -> list[FcwRow]:
    """Every FCW row, or those whose id matches one of ``patterns``."""
    rows = [row for row in fcw_rows() if not patterns or any(fnmatch.fnmatchcase(row.row_id, p) for p in patterns)]
    if not rows:
        raise ValueError("no FCW row matches the selection")
    return rows


def run_fcw_task(task: Task) -> TaskResult:
    """Drive and judge one task (in a worker process)."""
    traces = tuple(drive(task))
    return task, tuple(judge_fcw_run(task.row, trace) for trace in traces), traces


def _figure(outcome: FcwOutcome) -> float | None:
    """The worst figure of a row over every run: the smallest, or for 5.4.2 the farthest from the set distance."""
    figures = [figure for group in outcome.groups for run in group.runs if (figure := run.figure) is not None]
    if not figures:
        return None
    set_distance_m = outcome.row.set_distance_m
    if set_distance_m is not None:
        return max(figures, key=lambda value: abs(value - set_distance_m))
    return min(figures)


def _write_json(path: Path, outcomes: Sequence[FcwOutcome], settings: dict[str, Any]) -> None:
    """Write ``report.json``: the settings, the verdict and every row with every run."""
    rows = [
        {
            **asdict(o.row),
            "criterion": criterion(o.row),
            "worst_figure": _figure(o),
            "passed": o.passed,
            "plot": o.plot,
            "groups": [
                {"step_length_s": g.step_length_s, "passed": g.passed, "runs": [asdict(run) for run in g.runs]}
                for g in o.groups
            ],
        }
        for o in outcomes
    ]
    content = {
        "format": "csws-fcw-conformance-report/1",
        "standard": "GB/T 33577-2017; IVISTA-SM-ISI.SA.AEB-TP-A0-2023; NHTSA FCW confirmation test (2008); "
        "Euro NCAP AEB car-to-car (CCR)",
        "settings": settings,
        "verdict": {
            "passed": all(o.passed for o in outcomes),
            "rows": len(outcomes),
            "rows_failed": [o.row.row_id for o in outcomes if not o.passed],
        },
        "rows": rows,
    }
    path.write_text(json.dumps(content, indent=1) + "\n", encoding="utf-8")


def _write_markdown(path: Path, outcomes: Sequence[FcwOutcome], settings: dict[str, Any]) -> None:
    """Write ``report.md``: the verdict, one line per row with its worst figure, and the failed runs."""
    failed = [o for o in outcomes if not o.passed]
    lines = [
        "# FCW conformance report (GB/T 33577-2017 5.4-5.5, IVISTA A.1, NHTSA FCW, Euro NCAP CCR)",
        "",
        f"- verdict: **{verdict_text(not failed)}**",
        f"- step lengths: {', '.join(f'{s:g} s' for s in settings['step_lengths_s'])}; "
        f"{settings['repetitions']} runs per row and step length (NHTSA: 7); seed {settings['seed']}",
        f"- rows: {len(outcomes)}, failed: {len(failed)}",
        "",
        '"worst" is the smallest figure over every run and step length '
        "(5.4.2: the one farthest from the set distance; CCR: the margin to the latest useful warning, s). "
        "A CCR row whose subject is below V_min (4.3.3) finds the system in standby: no warning is required, "
        "and it passes whatever the system said.",
        "",
        "| row | clause | test | criterion | worst | verdict |",
        "|---|---|---|---|---|---|",
    ]
    for o in outcomes:
        figure = _figure(o)
        lines.append(
            f"| {o.row.row_id} | {o.row.source} {o.row.clause} | {o.row.title} | {criterion(o.row)} | "
            f"{'-' if figure is None else f'{figure:.2f}'} | {mark(o.passed)} |"
        )
    problems = [
        f"- {o.row.row_id} at {g.step_length_s:g} s, run {run.repetition + 1}: {run.reason}"
        for o in outcomes
        for g in o.groups
        for run in g.runs
        if not run.passed
    ]
    known = [f"- {o.row.row_id}: known cause: {o.row.known_issue}" for o in failed if o.row.known_issue]
    if problems:
        lines += ["", "## Failed runs", "", *known, *problems]
    if any(o.plot for o in outcomes):
        lines += ["", "## Plots", "", *(f"- [{o.row.row_id}]({o.plot})" for o in outcomes if o.plot)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def plot_fcw_row(path: Path, row: FcwRow, traces: Sequence[tuple[float, Trace]]) -> None:
    """True TTC and the warning level against the time to the end of each run, every run of a row."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot

    figure, (ttc_axis, level_axis) = pyplot.subplots(2, 1, sharex=True, figsize=(8, 5.5))
    colours = step_colours(sorted({step for step, _ in traces}))
    labelled = set()
    for step, trace in traces:
        before_end_s = trace.time_s - trace.time_s[-1]
        label = f"step {step:g} s" if step not in labelled else None
        labelled.add(step)
        ttc_axis.plot(before_end_s, np.minimum(trace.ttc_s, 10.0), color=colours[step], lw=0.8, alpha=0.7, label=label)
        level_axis.step(before_end_s, trace.level, where="post", color=colours[step], lw=0.8, alpha=0.7)
        warned = np.flatnonzero(trace.level >= row.level)
        if row.avoidance and warned.size:
            latest_s = before_end_s[warned[0]] + warning_margin_s(trace, int(warned[0]))
            level_axis.plot([latest_s], [row.level], marker="|", ms=14, color="tab:red", ls="none")
    if row.least_ttc_s is not None:
        ttc_axis.axhline(row.least_ttc_s, color="tab:red", ls="--", lw=0.8, label=f"least TTC {row.least_ttc_s:g} s")
    ttc_axis.set_ylabel("true TTC (s, capped at 10)")
    ttc_axis.legend(fontsize=7)
    if row.avoidance:
        level_axis.set_title("red |: the latest useful warning (0.8 s reaction, 0.68 g)", fontsize=8)
    level_axis.set_ylabel("warning level")
    level_axis.set_yticks([0, 1, 2])
    level_axis.set_xlabel("time before the end of the run (s)")
    ttc_axis.set_title(f"{row.row_id}: {row.title}", fontsize=9)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    pyplot.close(figure)


def fcw_conformance(
    rows: Sequence[FcwRow],
    out: Path,
    step_lengths_s: Sequence[float] = DEFAULT_STEP_LENGTHS_S,
    repetitions: int = 3,
    seed: int = 0,
    jobs: int = 1,
    plots: bool = True,
    progress: bool = False,
) -> list[FcwOutcome]:
    """Run, judge and report the rows into ``out`` (report.json, report.md, plots/ROW.png); the outcomes."""
    tasks = [Task(row, step, row.repetitions or repetitions, seed) for row in rows for step in step_lengths_s]
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    groups: dict[str, list[GroupOutcome[FcwRunResult]]] = {row.row_id: [] for row in rows}
    records: dict[str, list[tuple[float, Trace]]] = {row.row_id: [] for row in rows}
    for task, runs, traces in run_tasks(tasks, jobs, progress, worker=run_fcw_task):
        groups[task.row.row_id].append(GroupOutcome(task.track, task.step_length_s, runs, group_passes(task.row, runs)))
        records[task.row.row_id] += [(task.step_length_s, trace) for trace in traces]
    outcomes = []
    for row in rows:
        plot = None
        if plots:
            (out / "plots").mkdir(exist_ok=True)
            plot = f"plots/{row.row_id}.png"
            plot_fcw_row(out / plot, row, records[row.row_id])
        outcomes.append(RowOutcome(row, tuple(sorted(groups[row.row_id], key=lambda g: g.step_length_s)), plot))
    settings = {
        "step_lengths_s": list(step_lengths_s),
        "repetitions": repetitions,
        "seed": seed,
        "jobs": jobs,
        "tasks": len(tasks),
        "simulation_wall_time_s": round(time.perf_counter() - started, 3),
    }
    _write_json(out / "report.json", outcomes, settings)
    _write_markdown(out / "report.md", outcomes, settings)
    return outcomes


def main(args: argparse.Namespace) -> int:
    """``csws conformance --system fcw``: exit 0 when every row passes, 1 when one fails."""
    for option in ("tables", "categories", "directions"):
        if getattr(args, option):
            raise ValueError(f"--{option} applies to --system csws only")
    rows = select_fcw_rows(args.rows)
    started = time.perf_counter()
    outcomes = fcw_conformance(
        rows,
        args.out,
        args.step_lengths,
        args.repetitions,
        args.seed,
        args.jobs,
        plots=not args.no_plots,
        progress=True,
    )
    failed = [o.row.row_id for o in outcomes if not o.passed]
    for row_id in failed:
        print(f"FAIL {row_id}")
    print(
        f"FCW: {verdict_text(not failed)}; {len(outcomes)} rows, {len(failed)} failed, "
        f"in {time.perf_counter() - started:.1f} s; report: {args.out / 'report.md'}"
    )
    return 1 if failed else 0
