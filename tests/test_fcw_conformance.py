"""The FCW suite in SUMO: a representative subset of rows run for real at two step lengths, and
the judge on those runs against TTC and clearances computed here from the record and the
standard's numbers."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from markers import marks_its_tests

from csws.conformance.fcw.judge import judge_fcw_run
from csws.conformance.fcw.rows import LEAD_BRAKE_MPS2, fcw_rows
from csws.conformance.fcw.run import fcw_conformance, select_fcw_rows
from csws.conformance.fcw.scripts import TARGET_BRAKES
from csws.fcw.physics import STANDARD_GRAVITY_MPS2

SUBSET = ("GB-5.4.2", "GB-5.5.2.1.2", "GB-5.5.2.2", "GB-5.5.3.2-III", "IVISTA-A.1.2")
STEPS_S = (0.01, 0.2)


@pytest.fixture(scope="module")
@marks_its_tests("slow", "sumo")
def subset(tmp_path_factory):
    out = tmp_path_factory.mktemp("fcw-conformance")
    outcomes = fcw_conformance(select_fcw_rows(SUBSET), out, STEPS_S, seed=5)
    return out, {o.row.row_id: o for o in outcomes}


def _traces(outcome):
    from csws.conformance.fcw.drive import Task, drive

    return [trace for step in STEPS_S for trace in drive(Task(outcome.row, step, 3, 5))]


def test_the_rows_hold_the_standards_numbers():
    rows = {row.row_id: row for row in fcw_rows()}
    assert {rows[r].least_ttc_s for r in ("GB-5.5.2.1.1", "IVISTA-A.1.1-car", "IVISTA-A.1.1-truck")} == {2.1}
    assert rows["GB-5.5.2.1.2"].least_ttc_s == 2.4 and rows["GB-5.5.2.1.3"].least_ttc_s == 2.0
    braking = rows["GB-5.5.2.1.2"]
    assert (
        braking.actor("tv").ahead_m == 30.0 and braking.actor("sv").speed_mps == braking.actor("tv").speed_mps == 20.0
    )
    assert LEAD_BRAKE_MPS2 == pytest.approx(0.3 * STANDARD_GRAVITY_MPS2)
    assert rows["GB-5.4.1"].least_clearance_m == pytest.approx(12.0**2 / (2 * 6.67) + 0.8 * 12.0)
    ivista = rows["IVISTA-A.1.2"]
    assert (ivista.actor("sv").speed_mps * 3.6, ivista.actor("tv").speed_mps * 3.6) == pytest.approx((80.0, 20.0))
    lateral = rows["GB-5.5.3.1"]
    assert lateral.actor("adj").lane != lateral.actor("sv").lane == lateral.actor("tv").lane


def test_the_subset_passes_at_both_step_lengths_and_the_report_is_written(subset):
    out, outcomes = subset
    assert all(o.passed for o in outcomes.values()), [o.row.row_id for o in outcomes.values() if not o.passed]
    report = json.loads((out / "report.json").read_text())
    assert report["verdict"]["passed"] and len(report["rows"]) == len(SUBSET)
    assert all(
        len(row["groups"]) == len(STEPS_S) and all(len(g["runs"]) == 3 for g in row["groups"]) for row in report["rows"]
    )
    assert "| GB-5.5.2.1.2 |" in (out / "report.md").read_text()
    assert all((out / "plots" / f"{row_id}.png").stat().st_size > 0 for row_id in SUBSET)


def test_the_braking_lead_is_warned_at_the_ttc_of_the_record(subset):
    """5.5.2.1.2: at the first collision warning, -x_c / v_r from the record's true clearance and
    speeds is at least 2.4 s; the lead decelerated at 0.3 g; the runs start at different phases."""
    _, outcomes = subset
    outcome = outcomes["GB-5.5.2.1.2"]
    for trace in _traces(outcome):
        first = int(np.flatnonzero(trace.level >= 2)[0])
        ttc_s = trace.clearance_m[first] / (trace.subject_mps[first] - trace.target_mps[first])
        assert ttc_s >= 2.4 and judge_fcw_run(outcome.row, trace).figure == pytest.approx(ttc_s)
        braking = trace.phase_index == TARGET_BRAKES
        decel = -np.diff(trace.target_mps[braking]) / np.diff(trace.time_s[braking])
        assert decel[1:] == pytest.approx(LEAD_BRAKE_MPS2, abs=1e-6)
    assert len({group.runs[0].phase for group in outcome.groups}) == len(STEPS_S)


def test_the_judge_fails_a_late_warning_a_wrong_target_and_a_warning_beside_the_adjacent_vehicle(subset):
    _, outcomes = subset
    row = outcomes["IVISTA-A.1.2"].row
    trace = _traces(outcomes["IVISTA-A.1.2"])[0]
    late = np.where(trace.ttc_s >= 1.9, 0, 2).astype(np.int8)  # first on below 1.9 s
    assert not judge_fcw_run(row, replace(trace, level=late)).passed
    wrong = tuple("tv2" if level else target for target, level in zip(trace.target, trace.level, strict=False))
    assert not judge_fcw_run(row, replace(trace, target=wrong)).passed
    curve = outcomes["GB-5.5.3.2-III"].row
    curve_trace = _traces(outcomes["GB-5.5.3.2-III"])[0]
    beside = (np.abs(curve_trace.adjacent_ahead_m) < 5.0) & (curve_trace.phase_index == 1)
    assert beside.any() and judge_fcw_run(curve, curve_trace).passed
    assert not judge_fcw_run(
        curve, replace(curve_trace, level=np.where(beside, 1, curve_trace.level).astype(np.int8))
    ).passed


def test_the_two_lead_test_warns_twice_for_the_nearer_lead(subset):
    _, outcomes = subset
    for trace in _traces(outcomes["GB-5.5.2.2"]):
        warned = trace.level >= 2
        assert (warned & (trace.phase_index == 1)).any() and (warned & (trace.phase_index == TARGET_BRAKES)).any()
        assert {target for target, level in zip(trace.target, trace.level, strict=False) if level} == {"tv"}


@pytest.mark.sumo
def test_cli_runs_one_fcw_row_and_refuses_csws_options(tmp_path):
    command = [
        sys.executable,
        "-m",
        "csws",
        "conformance",
        "--system",
        "fcw",
        "--rows",
        "GB-5.5.2.1.1",
        "--step-lengths",
        "0.1",
        "--out",
        str(tmp_path),
        "--no-plots",
    ]
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0 and "FCW: PASS; 1 rows" in done.stdout
    refused = subprocess.run([*command, "--tables", "5"], capture_output=True, text=True)
    assert refused.returncode == 2 and refused.stderr.strip().splitlines() == [
        "csws: error: --tables applies to --system csws only"
    ]
