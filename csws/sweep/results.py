"""Each run's result: one Parquet file of one row, written whole the moment the run is done.

``DIR/runs/KEY.parquet`` (KEY: the run's hash, :attr:`csws.sweep.study.RunSpec.key`) is
written under a temporary name and renamed, so a file that exists is complete: a sweep that
is killed and started again skips exactly the runs whose file exists. Parquet (pyarrow)
keeps the types (the excess speeds at curve entry are one list column) and the aggregate
reads every run as one table.
"""

from __future__ import annotations

import os
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

__all__ = ["RUN_SCHEMA", "RUNS_FOLDER", "result_path", "write_result", "read_results"]

RUNS_FOLDER = "runs"
#: The columns of a run's row.
RUN_SCHEMA = pa.schema(
    [
        ("key", pa.string()),
        ("reference", pa.bool_()),
        ("seed", pa.int64()),
        ("equipped_share", pa.float64()),
        ("compliance_share", pa.float64()),
        ("reaction_s", pa.float64()),
        ("decel_mps2", pa.float64()),
        ("step_length_s", pa.float64()),
        ("category_mix", pa.string()),
        ("status", pa.string()),
        ("simulated_until_s", pa.float64()),
        ("vehicles", pa.int64()),
        ("vehicles_equipped", pa.int64()),
        ("vehicle_km", pa.float64()),
        ("vehicle_km_equipped", pa.float64()),
        ("entries_above_vw1", pa.int64()),
        ("entries_above_vw2", pa.int64()),
        ("share_vehicles_above_vw1", pa.float64()),
        ("share_vehicles_above_vw2", pa.float64()),
        ("warnings", pa.int64()),
        ("warnings_per_100_vehicle_km", pa.float64()),
        ("mean_time_loss_s", pa.float64()),
        ("entry_excess_kmh", pa.list_(pa.float64())),
    ]
)


def result_path(out: Path, key: str) -> Path:
    """Where the result of run ``key`` is kept."""
    return out / RUNS_FOLDER / f"{key}.parquet"


def write_result(out: Path, row: dict) -> Path:
    """Write one run's row to its file, whole (temporary name, then rename)."""
    path = result_path(out, row["key"])
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(f".partial-{os.getpid()}")
    pq.write_table(pa.Table.from_pylist([row], schema=RUN_SCHEMA), partial)
    os.replace(partial, path)
    return path


def read_results(out: Path, keys: list[str]) -> pa.Table:
    """The rows of the runs ``keys`` that are done, in the order of ``keys``."""
    paths = [result_path(out, key) for key in keys]
    tables = [pq.read_table(path, schema=RUN_SCHEMA) for path in paths if path.is_file()]
    return pa.concat_tables(tables) if tables else RUN_SCHEMA.empty_table()
