"""``csws sweep``: read the study, run what is not done on Dask, summarise what is."""

from __future__ import annotations

import argparse
import sys

from .aggregate import aggregate
from .execute import run_sweep
from .study import read_study

__all__ = ["main"]


def main(args: argparse.Namespace) -> int:
    """The ``csws sweep`` command: 0 when every run is done, 1 (with a line per failed run) otherwise."""
    study = read_study(args.study)
    runs = study.runs()
    report = run_sweep(runs, args.out, scheduler=args.scheduler, workers=args.workers)
    summary = aggregate(study, args.out)
    for key, error in report.failed.items():
        print(f"csws: error: run {key} failed: {error}", file=sys.stderr)
    print(
        f"{len(runs)} runs: {len(report.done_before)} done before, {len(report.ran)} now, "
        f"{len(report.failed)} failed; summary in {summary}"
    )
    return 1 if report.failed else 0
