"""``csws sweep`` on a real Dask LocalCluster of two worker processes, against the same runs one after another here.

A tiny study of the fleet scenario (a few vehicles, 40 simulated seconds): the rows the
cluster writes equal those of a plain loop in this process, also when a worker process is
killed mid-sweep; a resumed sweep runs only what is missing; a bad study file is one line.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import pytest
from markers import marks_its_tests

from csws.cli import main as csws_main
from csws.sweep.execute import run_sweep
from csws.sweep.results import RUNS_FOLDER, read_results, result_path, write_result
from csws.sweep.study import read_study
from csws.sweep.task import run_task

STUDY = """
[study]
name = "tiny"
seeds = 2

[scenario]
bundled = "fleet"
vehicles = 8
end_s = 40

[factors]
equipped_share = [0.5, 1.0]
compliance_share = [0.5, 1.0]
"""


@pytest.fixture(scope="module")
def study_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("study") / "tiny.toml"
    path.write_text(STUDY, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
@marks_its_tests("slow", "sumo")
def serial_rows(study_file) -> dict[str, dict]:
    """Every run of the study, one after another in this process: the truth the cluster is held to."""
    return {spec.key: run_task(spec) for spec in read_study(study_file).runs()}


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def cluster():
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as local:
        yield local


def _rows(out: Path, keys: list[str]) -> dict[str, dict]:
    return {row["key"]: row for row in read_results(out, keys).to_pylist()}


def test_the_study_has_every_setting_per_seed_and_the_fleet_without_csws(study_file):
    study = read_study(study_file)
    runs = study.runs()
    assert len(runs) == (2 * 2 + 1) * 2
    assert len({spec.key for spec in runs}) == len(runs)
    assert sum(spec.reference for spec in runs) == 2


def test_a_mix_named_but_not_run_leaves_the_runs_done(study_file, tmp_path):
    """A run's key hashes its own category mix: naming another mix in the study does not make it new."""
    more = tmp_path / "more.toml"
    more.write_text(STUDY + "\n[category_mixes.heavy]\nN = 0.6\nO = 0.4\n", encoding="utf-8")
    assert [spec.key for spec in read_study(more).runs()] == [spec.key for spec in read_study(study_file).runs()]


def test_two_workers_write_every_run_once_as_a_serial_run_does(study_file, serial_rows, cluster, tmp_path):
    study = read_study(study_file)
    report = run_sweep(study.runs(), tmp_path, scheduler=cluster.scheduler_address, progress=False)
    assert sorted(report.ran) == sorted(serial_rows) and not report.failed
    assert len(list((tmp_path / RUNS_FOLDER).iterdir())) == len(serial_rows)
    assert _rows(tmp_path, list(serial_rows)) == serial_rows
    equipped = [row for row in serial_rows.values() if row["equipped_share"] == 1.0 and row["compliance_share"] == 1.0]
    assert all(row["entries_above_vw1"] == 0 for row in equipped)  # the modelled driver brakes below V_w1 in time
    assert any(row["entries_above_vw1"] > 0 for row in serial_rows.values() if row["reference"])


def test_a_worker_killed_mid_sweep_loses_no_run_and_counts_none_twice(study_file, serial_rows, cluster, tmp_path):
    from dask.distributed import Client

    study = read_study(study_file)
    result: dict = {}
    sweep = threading.Thread(
        target=lambda: result.update(
            report=run_sweep(study.runs(), tmp_path, scheduler=cluster.scheduler_address, progress=False)
        )
    )
    with Client(cluster.scheduler_address) as client:
        pids = client.run(os.getpid)
        sweep.start()
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            busy = [worker for worker, keys in client.processing().items() if keys]
            if busy and len(list((tmp_path / RUNS_FOLDER).glob("*.parquet"))) >= 1:
                os.kill(pids[busy[0]], signal.SIGKILL)
                break
            time.sleep(0.02)
        else:
            pytest.fail("no worker was running a task")
        sweep.join(timeout=120)
        keys = [f"csws-run-{spec.key}" for spec in study.runs()]
        started = client.run_on_scheduler(
            lambda dask_scheduler: [
                sum(transition[2] == "processing" for transition in dask_scheduler.story(key)) for key in keys
            ]
        )
        assert client.run(os.getpid) != pids  # the killed worker was replaced
    assert max(started) >= 2  # the killed worker's run was started again elsewhere
    report = result["report"]
    assert not report.failed and sorted(report.ran) == sorted(serial_rows)
    assert len(list((tmp_path / RUNS_FOLDER).iterdir())) == len(serial_rows)
    assert _rows(tmp_path, list(serial_rows)) == serial_rows


def test_a_resumed_sweep_runs_only_the_missing_runs(study_file, serial_rows, cluster, tmp_path):
    study = read_study(study_file)
    runs = study.runs()
    run_sweep(runs, tmp_path, scheduler=cluster.scheduler_address, progress=False)
    missing = [runs[1].key, runs[-1].key]
    kept = {spec.key: result_path(tmp_path, spec.key).stat().st_mtime_ns for spec in runs if spec.key not in missing}
    for key in missing:
        result_path(tmp_path, key).unlink()
    report = run_sweep(runs, tmp_path, scheduler=cluster.scheduler_address, progress=False)
    assert sorted(report.ran) == sorted(missing)
    assert sorted(report.done_before) == sorted(kept)
    assert {key: result_path(tmp_path, key).stat().st_mtime_ns for key in kept} == kept
    assert _rows(tmp_path, list(serial_rows)) == serial_rows


def test_the_command_summarises_the_study_with_intervals_and_plots(study_file, serial_rows, tmp_path, capsys):
    out = tmp_path / "out"
    (out / RUNS_FOLDER).mkdir(parents=True)
    for row in serial_rows.values():
        write_result(out, row)
    assert csws_main(["sweep", str(study_file), "--out", str(out)]) == 0
    assert "10 runs: 10 done before, 0 now, 0 failed" in capsys.readouterr().out
    summary = (out / "summary.md").read_text()
    assert "| 1 | 1 | 0 ± 0 |" in summary  # every vehicle equipped and complying: none above V_w1 in any seed
    assert (out / "plots" / "summary.png").stat().st_size > 10_000
    assert (out / "plots" / "excess.png").stat().st_size > 5_000
    assert summary.count("\n| ") == 1 + 4 + 1 + len(serial_rows)  # header + settings, header + runs


BAD_STUDIES = {
    "share above 1": (
        "[study]\nseeds = 2\n[scenario]\nbundled = 'fleet'\nend_s = 10\n[factors]\nequipped_share = [0.5, 1.5]\n",
        "factors.equipped_share: 1.5 is not a share in [0, 1]",
    ),
    "unknown factor": (
        "[study]\nseeds = 2\n[scenario]\nbundled = 'fleet'\nend_s = 10\n[factors]\nspeed = 3\n",
        "factors.speed: unknown field",
    ),
    "no seeds": ("[scenario]\nbundled = 'fleet'\nend_s = 10\n", "study.seeds: is missing"),
    "zero seeds": (
        "[study]\nseeds = 0\n[scenario]\nbundled = 'fleet'\nend_s = 10\n",
        "study.seeds: 0 is not a whole number",
    ),
    "bad step": (
        "[study]\nseeds = 1\n[scenario]\nbundled = 'fleet'\nend_s = 10\n[factors]\nstep_length_s = 0.0005\n",
        "factors.step_length_s: a step length must be a multiple of 0.001 s in (0, 1]",
    ),
    "no end": ("[study]\nseeds = 1\n[scenario]\nbundled = 'fleet'\n", "scenario.end_s: is missing"),
    "unknown scenario": (
        "[study]\nseeds = 1\n[scenario]\nbundled = 'paris'\nend_s = 10\n",
        "scenario.bundled: 'paris' is not one of fleet, badhersfeld",
    ),
    "missing sumocfg": (
        "[study]\nseeds = 1\n[scenario]\nsumocfg = 'nowhere.sumocfg'\nend_s = 10\n",
        "scenario.sumocfg: no such SUMO configuration",
    ),
    "unknown mix": (
        "[study]\nseeds = 1\n[scenario]\nbundled = 'fleet'\nend_s = 10\n[factors]\ncategory_mix = ['heavy']\n",
        "factors.category_mix: 'heavy' is neither scenario nor a [category_mixes.heavy] table",
    ),
    "bad category": (
        "[study]\nseeds = 1\n[scenario]\nbundled = 'fleet'\nend_s = 10\n[category_mixes.heavy]\nN3 = 1\n",
        "category_mixes.heavy.N3: unknown field",
    ),
    "not toml": ("[study\nseeds = 1\n", "not TOML"),
}


@pytest.mark.parametrize("text, message", BAD_STUDIES.values(), ids=BAD_STUDIES.keys())
def test_a_bad_study_is_one_line_naming_the_field_before_anything_runs(text, message, tmp_path, capsys):
    study = tmp_path / "bad.toml"
    study.write_text(text, encoding="utf-8")
    assert csws_main(["sweep", str(study), "--out", str(tmp_path / "out")]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"csws: error: {study}: ") and message in lines[0], captured.err
    assert not (tmp_path / "out").exists()
