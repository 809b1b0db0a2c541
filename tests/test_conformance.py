"""The test procedure of 7.5 in SUMO: a representative subset of rows run for real, and the judge.

Rows come from the standard's tables (``csws.data.standard_tables``); distances from the
tracks' generator-written truth files; the warning onsets are bounded with formula (1)
computed here from the test speed and Tables 1-2.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from markers import marks_its_tests

from csws.conformance.drive import POSITION_ACCURACY_M, Task, Trace, drive, truth
from csws.conformance.judge import CONSECUTIVE_PASSES, consecutive_passes, judge_run
from csws.conformance.rows import procedure_rows
from csws.conformance.run import conformance, select_rows
from csws.data import standard_tables
from csws.standard import Category, kmh_to_mps, warning_distance, warning_speed
from csws.warning.rules import WarningSettings

TABLES = standard_tables()
#: One row per table (and the negative rows), spread over the categories and radii.
SUBSET = ("T5-R40-M1-V51", "T6-R200-N-V114", "T7-M2", "T8-O-test1", "T9-M1-test1", "NEG-R120-M3-L1")
STEPS_S = (0.01, 0.2)


@pytest.fixture(scope="module")
@marks_its_tests("slow", "sumo")
def subset_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("conformance")
    outcomes = conformance(select_rows(patterns=SUBSET), out, STEPS_S, seed=3, jobs=1)
    return out, outcomes


def test_rows_cover_every_cell_of_tables_5_to_9_for_every_category():
    rows = procedure_rows()
    members = {column: [c for c in Category if c.column.value == column] for column in TABLES["categories"]}
    single = sum(
        len(cells) * len(members[column])
        for key in ("table5_single_curve_level1_tests", "table6_single_curve_level2_tests")
        for radius, columns in TABLES[key].items()
        if not radius.startswith("_")
        for column, cells in columns.items()
    )
    multi = sum(len(members[c]) for c in TABLES["categories"]) + sum(
        len(TABLES[key][column]) * len(members[column])
        for key in ("table8_multi_curve_curve2_first_all_before_curve1", "table9_multi_curve_curve2_first_alternating")
        for column in TABLES["categories"]
    )
    assert len([r for r in rows if r.table in (5, 6)]) == single
    assert len([r for r in rows if r.table in (7, 8, 9)]) == multi
    assert len({r.row_id for r in rows}) == len(rows)
    for row in rows:
        for track in row.tracks:  # each row runs on tracks whose curves are the row's
            assert [c for c in truth(track).curve_start_s_m] and len(truth(track).curve_start_s_m) == len(row.radius_m)


def test_the_subset_passes_at_both_step_lengths(subset_report):
    out, outcomes = subset_report
    assert [o.row.row_id for o in outcomes] == list(SUBSET)
    failed = [
        (o.row.row_id, g.track, g.step_length_s, [c.reason for r in g.runs for c in r.checks if not c.passed])
        for o in outcomes
        for g in o.groups
        if not g.passed
    ]
    assert not failed
    steps = {g.step_length_s for o in outcomes for g in o.groups}
    assert steps == set(STEPS_S)


def test_warnings_come_before_the_table_distance_and_single_curves_not_long_before_formula_1(subset_report):
    _, outcomes = subset_report
    latency = WarningSettings()
    for outcome in outcomes:
        row = outcome.row
        for group in outcome.groups:
            speed_mps = kmh_to_mps(row.speed_kmh)
            for run in group.runs:
                for check, result in zip(row.checks, run.checks, strict=False):
                    if check.negative or row.final_speed_kmh is not None:
                        continue
                    v_w = warning_speed(row.radius_m[check.curve_number - 1], row.category, check.level)
                    formula_m = warning_distance(row.speed_kmh, v_w)
                    assert result.earlier_m >= 0
                    # The system looks ahead only by its latency allowance plus one step's travel.
                    slack_m = speed_mps * (group.step_length_s + latency.system_delay_s + group.step_length_s)
                    if row.table in (5, 6):  # one curve: the onset is this check's own warning
                        assert result.onset_distance_m <= formula_m + slack_m + 2 * POSITION_ACCURACY_M + 1.0


def test_repetitions_start_at_different_phases_and_hold_the_speed_3_s(subset_report):
    _, outcomes = subset_report
    for outcome in outcomes:
        for group in outcome.groups:
            phases = [run.phase for run in group.runs]
            assert len(set(phases)) == len(phases) >= CONSECUTIVE_PASSES
            assert all(run.stable_s >= 3.0 for run in group.runs)


def test_the_negative_row_never_warns_and_the_run_outs_are_quiet(subset_report):
    _, outcomes = subset_report
    negative = next(o for o in outcomes if o.row.negative)
    assert negative.max_level(0) == 0
    assert all(run.runout_level == 0 for o in outcomes for g in o.groups for run in g.runs)


def test_report_files_are_written(subset_report):
    out, outcomes = subset_report
    report = json.loads((out / "report.json").read_text())
    assert report["verdict"]["clause_7_6_passed"] is True
    assert report["verdict"]["negative_rows_passed"] is True
    markdown = (out / "report.md").read_text()
    assert "Table 7" in markdown and "Table 9" in markdown and "**FAIL**" not in markdown
    for outcome in outcomes:
        assert (out / outcome.plot).stat().st_size > 10_000


@pytest.mark.sumo
def test_table_7_brakes_at_4_9_mps2_within_curve_1s_level_2_distance():
    row = next(r for r in procedure_rows() if r.row_id == "T7-M3")
    trace = drive(Task(row, row.tracks[0], 0.05, 3, seed=0))[0]
    start_s = truth(row.tracks[0]).curve_start_s_m[0]
    decel = -np.diff(kmh_to_mps(trace.speed_kmh)) / np.diff(trace.time_s)
    braking = np.flatnonzero(decel > 0.1)
    assert decel[braking[:-1]] == pytest.approx(4.9, abs=1e-6)  # the last step reaches the final speed
    first_distance_m = start_s - trace.route_s_m[braking[0]]
    assert first_distance_m <= row.decel_trigger_m
    assert trace.speed_kmh[-1] == pytest.approx(row.final_speed_kmh)


def _trace(distance_m: np.ndarray, level: np.ndarray, speed_kmh: float, start_s: float) -> Trace:
    return Trace(
        0,
        0.0,
        np.arange(distance_m.size) * 0.1,
        start_s - distance_m,
        np.full(distance_m.size, speed_kmh),
        np.asarray(level, dtype=np.int8),
    )


def test_the_judge_fails_a_late_warning_and_one_that_goes_off_before_the_curve():
    row = next(r for r in procedure_rows() if r.row_id == "T5-R40-M1-V51")
    track_truth = truth(row.tracks[0])
    start_s = track_truth.curve_start_s_m[0]
    distance_m = np.arange(200.0, -100.0, -1.4)
    table_m = row.checks[0].table_distance_m
    first_below = np.flatnonzero(distance_m < table_m)[0]
    on_time = np.where((distance_m < table_m + 1) & (distance_m > 0), 1, 0)
    late = on_time.copy()
    late[first_below] = 0
    gap = on_time.copy()
    gap[first_below + 3] = 0
    runout = on_time.copy()
    runout[-1] = 1
    assert judge_run(row, _trace(distance_m, on_time, row.speed_kmh, start_s), track_truth).passed
    for level in (late, gap, runout):
        assert not judge_run(row, _trace(distance_m, level, row.speed_kmh, start_s), track_truth).passed


def test_three_consecutive_passes_are_needed():
    row = next(r for r in procedure_rows() if r.row_id == "T5-R40-M1-V51")
    track_truth = truth(row.tracks[0])
    start_s = track_truth.curve_start_s_m[0]
    distance_m = np.arange(200.0, -100.0, -1.4)
    good = np.where((distance_m < 20) & (distance_m > 0), 1, 0)
    runs = [
        judge_run(row, _trace(distance_m, level, row.speed_kmh, start_s), track_truth)
        for level in (good, good, good * 0, good, good)
    ]
    runs = [type(r)(i, r.phase, r.stable_s, r.runout_level, r.checks, r.passed) for i, r in enumerate(runs)]
    assert not consecutive_passes(runs)
    assert consecutive_passes(runs + [type(runs[0])(5, 0.0, 10.0, 0, runs[0].checks, True)])


def test_cli_rejects_too_few_repetitions_in_one_line(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "csws", "conformance", "--out", str(tmp_path), "--repetitions", "2", "--rows", "T7-M1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.strip().startswith("csws: error:") and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.slow
@pytest.mark.sumo
def test_cli_runs_a_row_and_exits_0(tmp_path):
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "csws",
            "conformance",
            "--out",
            str(tmp_path),
            "--rows",
            "T8-M1-test2",
            "--step-lengths",
            "0.1",
            "--directions",
            "left",
            "--jobs",
            "2",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "7.6: PASS" in result.stdout
    assert (tmp_path / "plots" / "T8-M1-test2.png").is_file()
    # stderr is a pipe here, not a terminal: progress comes as lines, the last at the end
    assert result.stderr.strip().splitlines()[-1].startswith("csws conformance: ")
    assert result.stderr.strip().endswith("(100 %)")
