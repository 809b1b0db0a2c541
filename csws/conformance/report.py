"""The conformance report: ``report.json``, ``report.md`` (tables shaped like the standard's) and plots.

The report is built from :class:`RowOutcome` records, one per row: its runs' results,
grouped by track and step length, and its verdict. The Markdown tables follow the
layout of Tables 5 to 9 (one column per category and test speed for the single curves;
one row per category and test, one column per warning for the multi curves) with the
worst run's warning onset and margin in each cell.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Generic, Protocol, TypeVar

import numpy as np

from .drive import Trace, Truth
from .judge import RunResult
from .realroads import REAL_ROAD_TABLE, required_levels
from .rows import Row

__all__ = [
    "GroupOutcome",
    "RowOutcome",
    "CswsOutcome",
    "verdict_text",
    "mark",
    "step_colours",
    "write_json",
    "write_markdown",
    "plot_row",
]

_TABLE_TITLES = {
    5: "Table 5: single curve, level 1 (7.5.2.1)",
    6: "Table 6: single curve, level 2 (7.5.2.2)",
    7: "Table 7: multi curve, curve 1 warned first (7.5.3.1)",
    8: "Table 8: multi curve, curve 2 warned first, all before curve 1 (7.5.3.2)",
    9: "Table 9: multi curve, curve 2 and curve 1 warnings alternate (7.5.3.3)",
    0: "Negative rows: 3 km/h below each warning speed, no warning of that level (6.1)",
    10: "Real-road tracks, judged by formula (1) on the constructed truth (6.1, 6.2.1)",
}
#: The tables of clause 7.5, which 7.6 judges.
PROCEDURE_TABLES = (5, 6, 7, 8, 9)


class _Judged(Protocol):
    """A judged run: whether it passed."""

    @property
    def passed(self) -> bool: ...


#: The rows of a suite (CSWS's :class:`~csws.conformance.rows.Row`, FCW's ``FcwRow``).
RowT = TypeVar("RowT")
#: The judged runs of a suite (CSWS's :class:`~csws.conformance.judge.RunResult`, FCW's ``FcwRunResult``).
RunT = TypeVar("RunT", bound=_Judged)


@dataclass(frozen=True)
class GroupOutcome(Generic[RunT]):
    """A row's runs on one track at one step length.

    Attributes
    ----------
    track, step_length_s
        Where and how finely it ran.
    runs
        The judged runs, in repetition order.
    passed
        Whether three consecutive runs passed.
    """

    track: str
    step_length_s: float
    runs: tuple[RunT, ...]
    passed: bool


@dataclass(frozen=True)
class RowOutcome(Generic[RowT, RunT]):
    """A row with every group of runs and its verdict (of either suite, CSWS's or FCW's).

    Attributes
    ----------
    row
        The row.
    groups
        Its runs by track and step length.
    plot
        File name of its plot, relative to the output folder, or None.
    """

    row: RowT
    groups: tuple[GroupOutcome[RunT], ...]
    plot: str | None

    @property
    def passed(self) -> bool:
        """The row passes when every group passes."""
        return all(group.passed for group in self.groups)

    def worst_earlier_m(self: CswsOutcome, check_index: int) -> float | None:
        """The smallest margin by which the warning of a check came before the table's S_w, m."""
        margins = [
            earlier_m
            for group in self.groups
            for run in group.runs
            if (earlier_m := run.checks[check_index].earlier_m) is not None
        ]
        return min(margins) if margins else None

    def max_level(self: CswsOutcome, check_index: int) -> int:
        """The highest level any run gave (what a negative check is about)."""
        return max(run.checks[check_index].max_level for group in self.groups for run in group.runs)


#: A row of the CSWS suite with its runs.
CswsOutcome = RowOutcome[Row, RunResult]


def _row_record(outcome: CswsOutcome) -> dict[str, Any]:
    """A row's JSON record."""
    row = outcome.row
    return {
        "row_id": row.row_id,
        "table": row.table,
        "clause": row.clause,
        "category": row.category.value,
        "column": row.column.value,
        "test": row.test,
        "radius_m": list(row.radius_m),
        "speed_kmh": row.speed_kmh,
        "final_speed_kmh": row.final_speed_kmh,
        "checks": [
            {
                "label": check.label,
                "curve_number": check.curve_number,
                "level": int(check.level),
                "table_distance_m": check.table_distance_m,
                "warning_speed_kmh": row.warning_speed_kmh(check),
                "worst_earlier_m": outcome.worst_earlier_m(index),
                "max_level": outcome.max_level(index),
            }
            for index, check in enumerate(row.checks)
        ],
        "groups": [
            {
                "track": group.track,
                "step_length_s": group.step_length_s,
                "passed": group.passed,
                "runs": [asdict(run) for run in group.runs],
            }
            for group in outcome.groups
        ],
        "passed": outcome.passed,
        "plot": outcome.plot,
    }


def verdicts(outcomes: Sequence[CswsOutcome]) -> dict[str, Any]:
    """The overall verdicts: 7.6 over Tables 5-9, our negative rows, and the real-road tracks."""

    def passed(table: int | tuple[int, ...]) -> bool | None:
        tables = table if isinstance(table, tuple) else (table,)
        selected = [o for o in outcomes if o.row.table in tables]
        return all(o.passed for o in selected) if selected else None

    return {
        "clause_7_6_passed": passed(PROCEDURE_TABLES),
        "negative_rows_passed": passed(0),
        "real_road_tracks_passed": passed(REAL_ROAD_TABLE),
        "rows": len(outcomes),
        "rows_failed": [o.row.row_id for o in outcomes if not o.passed],
    }


def write_json(path: Path, outcomes: Sequence[CswsOutcome], settings: dict[str, Any]) -> None:
    """Write ``report.json``: the settings, the verdicts and every row with every run."""
    content = {
        "format": "csws-conformance-report/1",
        "standard": "T/ITS 0091-2018",
        "settings": settings,
        "verdict": verdicts(outcomes),
        "rows": [_row_record(o) for o in outcomes],
    }
    path.write_text(json.dumps(content, indent=1) + "\n", encoding="utf-8")


def verdict_text(passed: bool | None) -> str:
    """An overall verdict."""
    return "PASS" if passed else "FAIL" if passed is not None else "not run"


def mark(passed: bool) -> str:
    """A verdict cell."""
    return "pass" if passed else "**FAIL**"


def _metres(value: float | None) -> str:
    """A distance cell, or a dash."""
    return "-" if value is None else f"{value:.1f}"


def _single_table(outcomes: Sequence[CswsOutcome]) -> list[str]:
    """Tables 5 and 6 as in the standard: one row block per radius, one column per category and speed."""
    columns = sorted({(o.row.category.value, o.row.speed_kmh) for o in outcomes}, key=lambda c: (c[0], c[1]))
    by_key = {(o.row.radius_m[0], o.row.category.value, o.row.speed_kmh): o for o in outcomes}
    header = "| R/m | | " + " | ".join(f"{category}" for category, _ in columns) + " |"
    lines = [header, "|" + "---|" * (len(columns) + 2)]
    for radius_m in sorted({o.row.radius_m[0] for o in outcomes}):
        cells = [by_key.get((radius_m, category, speed)) for category, speed in columns]
        lines.append(
            f"| {radius_m:g} | V/(km/h) | "
            + " | ".join("" if o is None else f"{o.row.speed_kmh:g}" for o in cells)
            + " |"
        )
        lines.append(
            "| | S_w/m | "
            + " | ".join("" if o is None else f"{o.row.checks[0].table_distance_m:g}" for o in cells)
            + " |"
        )
        lines.append(
            "| | earlier/m | " + " | ".join("" if o is None else _metres(o.worst_earlier_m(0)) for o in cells) + " |"
        )
        lines.append("| | verdict | " + " | ".join("" if o is None else mark(o.passed) for o in cells) + " |")
    return lines


def _multi_table(outcomes: Sequence[CswsOutcome]) -> list[str]:
    """Tables 7 to 9: one line per category and test, one column group per warning."""
    labels = [check.label for check in outcomes[0].row.checks]
    lines = [
        "| category | test | R1/m | V/(km/h) | "
        + " | ".join(f"{label}: S_w/m, earlier/m" for label in labels)
        + " | verdict |",
        "|" + "---|" * (len(labels) + 5),
    ]
    for o in outcomes:
        row = o.row
        speed = f"{row.speed_kmh:g}" + (f" -> {row.final_speed_kmh:g}" if row.final_speed_kmh is not None else "")
        cells = [f"{check.table_distance_m:g}, {_metres(o.worst_earlier_m(i))}" for i, check in enumerate(row.checks)]
        lines.append(
            f"| {row.category.value} | {row.test or ''} | {row.radius_m[0]:g} | {speed} | "
            + " | ".join(cells)
            + f" | {mark(o.passed)} |"
        )
    return lines


def _negative_table(outcomes: Sequence[CswsOutcome]) -> list[str]:
    """Our negative rows: radius, category, level, speed and the highest level seen."""
    lines = ["| R/m | category | level | V/(km/h) | highest level given | verdict |", "|---|---|---|---|---|---|"]
    for o in outcomes:
        row, check = o.row, o.row.checks[0]
        lines.append(
            f"| {row.radius_m[0]:g} | {row.category.value} | {int(check.level)} | {row.speed_kmh:.0f} | "
            f"{o.max_level(0)} | {mark(o.passed)} |"
        )
    return lines


def _real_road_table(outcomes: Sequence[CswsOutcome]) -> list[str]:
    """The real-road rows: track, category, speed, and per level how much earlier than formula (1)
    the warning came on (the smallest margin of any run; negative: later) and the verdict."""
    lines = [
        "| track | category | V/(km/h) | level 1 earlier/m | level 2 earlier/m | verdict |",
        "|---|---|---|---|---|---|",
    ]
    for o in outcomes:
        row = o.row
        lines.append(
            f"| {row.tracks[0]} | {row.category.value} | {row.speed_kmh:g} | {_metres(o.worst_earlier_m(0))} | "
            f"{_metres(o.worst_earlier_m(1))} | {mark(o.passed)} |"
        )
    return lines


def _failures(outcomes: Sequence[CswsOutcome]) -> list[str]:
    """One line per failed run check: what went wrong where."""
    lines = []
    for o in outcomes:
        for group in o.groups:
            for run in group.runs:
                problems = [f"{c.label}: {c.reason}" for c in run.checks if not c.passed]
                if run.runout_level:
                    problems.append(f"level {run.runout_level} on the straight run-out")
                if problems:
                    lines.append(
                        f"- {o.row.row_id} on {group.track} at {group.step_length_s:g} s, run {run.repetition + 1}: "
                        + "; ".join(problems)
                    )
    return lines


def write_markdown(path: Path, outcomes: Sequence[CswsOutcome], settings: dict[str, Any]) -> None:
    """Write ``report.md``: the verdicts, then one table per table of the standard."""
    verdict = verdicts(outcomes)
    overall = verdict["clause_7_6_passed"]
    lines = [
        "# CSWS conformance report (T/ITS 0091-2018, clause 7.5)",
        "",
        f"- 7.6 verdict: **{verdict_text(overall)}**",
        f"- negative rows: **{verdict_text(verdict['negative_rows_passed'])}**",
        f"- real-road tracks: **{verdict_text(verdict['real_road_tracks_passed'])}**",
        f"- step lengths: {', '.join(f'{s:g} s' for s in settings['step_lengths_s'])}; "
        f"{settings['repetitions']} runs per row, track and step length; seed {settings['seed']}",
        f"- rows: {verdict['rows']}, failed: {len(verdict['rows_failed'])}",
        "",
        '"earlier/m" is the smallest margin over every run, track and step length by which the',
        "warning came on before the table's S_w (the true distance to the curve start, from the",
        "track's truth file). On the real-road tracks it is the margin by which each level came on",
        "before formula (1) first required it at some point of the road (negative: after).",
    ]
    for table in (*PROCEDURE_TABLES, 0, REAL_ROAD_TABLE):
        selected = [o for o in outcomes if o.row.table == table]
        if not selected:
            continue
        shapes = {5: _single_table, 6: _single_table, 0: _negative_table, REAL_ROAD_TABLE: _real_road_table}
        shape = shapes.get(table, _multi_table)
        lines += ["", f"## {_TABLE_TITLES[table]}", "", *shape(selected)]
    failures = _failures(outcomes)
    if failures:
        lines += ["", "## Failed runs", "", *failures]
    plots = [o.plot for o in outcomes if o.plot]
    if plots:
        lines += ["", "## Plots", "", *(f"- [{o.row.row_id}]({o.plot})" for o in outcomes if o.plot)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def step_colours(steps: Sequence[float]) -> dict[float, Any]:
    """One colour per step length for the plots, from the viridis map (its light end left out)."""
    from matplotlib import pyplot

    shades = pyplot.get_cmap("viridis")(np.linspace(0, 0.85, max(len(steps), 1)))
    return dict(zip(steps, shades, strict=False))


def plot_row(path: Path, row: Row, traces: Sequence[tuple[Truth, float, Trace]]) -> None:
    """Speed and warning level against the distance to the first curve's start, every run of a row.

    ``traces`` holds each run with its track's truth and step length. Vertical lines mark
    where each check's table S_w lies and where the curves start.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot

    figure, (speed_axis, level_axis) = pyplot.subplots(2, 1, sharex=True, figsize=(8, 5.5))
    _plot_runs(speed_axis, level_axis, traces)
    track_truth = traces[0][0]
    _mark_curves(speed_axis, level_axis, track_truth)
    if row.table == REAL_ROAD_TABLE:
        _plot_required(level_axis, row, track_truth, traces[0][2])
    _mark_table_distances(level_axis, row, track_truth)
    speed_axis.set_ylabel("speed (km/h)")
    speed_axis.legend(fontsize=7)
    level_axis.set_ylabel("warning level")
    level_axis.set_yticks([0, 1, 2])
    level_axis.set_ylim(-0.2, 2.6)
    level_axis.set_xlabel("distance to the start of the first curve (m)")
    level_axis.invert_xaxis()
    speed_axis.set_title(f"{row.row_id} ({row.clause}, {row.category.value}, {row.speed_kmh:g} km/h)")
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    pyplot.close(figure)


def _plot_runs(speed_axis: Any, level_axis: Any, traces: Sequence[tuple[Truth, float, Trace]]) -> None:
    """Every run's speed and level against the distance to the first curve, coloured by step length."""
    colours = step_colours(sorted({step for _, step, _ in traces}))
    labelled = set()
    for track_truth, step, trace in traces:
        distance_m = track_truth.curve_start_s_m[0] - trace.route_s_m
        label = f"step {step:g} s" if step not in labelled else None
        labelled.add(step)
        speed_axis.plot(distance_m, trace.speed_kmh, color=colours[step], lw=0.8, alpha=0.7, label=label)
        level_axis.step(distance_m, trace.level, where="post", color=colours[step], lw=0.8, alpha=0.7)


def _mark_curves(speed_axis: Any, level_axis: Any, track_truth: Truth) -> None:
    """A vertical line where each curve starts, named on the level axis."""
    for number, start_s in enumerate(track_truth.curve_start_s_m, start=1):
        offset_m = track_truth.curve_start_s_m[0] - start_s
        for axis in (speed_axis, level_axis):
            axis.axvline(offset_m, color="black", lw=0.8)
        level_axis.annotate(f"curve {number}", (offset_m, 2.25), fontsize=7, ha="left")


def _plot_required(level_axis: Any, row: Row, track_truth: Truth, trace: Trace) -> None:
    """What formula (1) requires of a real-road run at each of its steps, from the constructed road."""
    required = required_levels(
        row, track_truth.name, trace.route_s_m, trace.speed_kmh, np.zeros(len(trace.route_s_m)), 0.0, 0.0
    )
    level_axis.step(
        track_truth.curve_start_s_m[0] - trace.route_s_m,
        required + 0.05,
        where="post",
        color="black",
        ls="--",
        lw=0.8,
        label="formula (1) requires",
    )
    level_axis.legend(fontsize=7, loc="upper left")


def _mark_table_distances(level_axis: Any, row: Row, track_truth: Truth) -> None:
    """A dashed line at each check's table S_w before its curve."""
    marked = [(check, distance_m) for check in row.checks if (distance_m := check.table_distance_m) is not None]
    for number, (check, table_distance_m) in enumerate(marked):
        offset_m = track_truth.curve_start_s_m[0] - track_truth.curve_start_s_m[check.curve_number - 1]
        position_m = offset_m + table_distance_m
        level_axis.axvline(position_m, color="tab:red", ls="--", lw=0.8)
        # Marks of one row often lie a few metres apart: their labels go one above the other.
        level_axis.annotate(
            f"S_w {check.label}",
            (position_m, 0.15 + 0.4 * number),
            fontsize=7,
            color="tab:red",
            ha="right",
            xytext=(-2, 0),
            textcoords="offset points",
        )
