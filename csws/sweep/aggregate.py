"""What a study shows: per setting, its figures with and without CSWS, with confidence intervals over seeds.

Every setting (combination of factor levels) ran once per seed; so did the fleet without CSWS
for each setting of the traffic factors. A figure of a setting is the mean over its seeds with
a 95 % confidence interval, mean +- t(0.975, n - 1) * s / sqrt(n) (Student's t: the seeds are
few). The change in time loss is paired: each seed's run against the same seed without CSWS,
the same vehicles on the same roads, so the interval is that of the differences.

Written into the output folder: ``summary.md`` (the settings' table, the plots, one table of
all runs), ``plots/summary.png`` and ``plots/excess.png`` (:mod:`csws.sweep.plots`), and
``all_runs.parquet`` (every run's row, the excess speeds included).
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass
from pathlib import Path

import pyarrow.parquet as pq

from .results import read_results
from .study import FACTORS, TRAFFIC_FACTORS, Factors, Study

__all__ = ["level_text", "Estimate", "SettingFigures", "setting_figures", "write_summary_md", "aggregate", "t_quantile"]

#: Student's t, 0.975 quantile, for 1-30 degrees of freedom.
_T_975 = (
    12.706,
    4.303,
    3.182,
    2.776,
    2.571,
    2.447,
    2.365,
    2.306,
    2.262,
    2.228,
    2.201,
    2.179,
    2.160,
    2.145,
    2.131,
    2.120,
    2.110,
    2.101,
    2.093,
    2.086,
    2.080,
    2.074,
    2.069,
    2.064,
    2.060,
    2.056,
    2.052,
    2.048,
    2.045,
    2.042,
)
#: The figures per setting: (name in the run's row, heading).
FIGURES = (
    ("share_vehicles_above_vw1", "vehicles entering a curve above V_w1, share"),
    ("share_vehicles_above_vw2", "vehicles entering a curve above V_w2, share"),
    ("warnings_per_100_vehicle_km", "warnings per 100 vehicle-km (equipped vehicles)"),
    ("mean_time_loss_s", "time loss per vehicle, s"),
)


def t_quantile(degrees: int) -> float:
    """Student's t 0.975 quantile for ``degrees`` degrees of freedom (the normal's beyond 30)."""
    return _T_975[degrees - 1] if degrees <= len(_T_975) else statistics.NormalDist().inv_cdf(0.975)


@dataclass(frozen=True)
class Estimate:
    """A mean over seeds with its 95 % confidence interval's half width (nan with one seed)."""

    mean: float
    half_width: float
    seeds: int

    @classmethod
    def of(cls, values: list[float | None]) -> Estimate:
        """The estimate from one value per seed; None (a figure without a denominator) is left out."""
        known = [v for v in values if v is not None]
        if not known:
            return cls(math.nan, math.nan, 0)
        if len(known) == 1:
            return cls(known[0], math.nan, 1)
        return cls(
            statistics.fmean(known),
            t_quantile(len(known) - 1) * statistics.stdev(known) / math.sqrt(len(known)),
            len(known),
        )

    def text(self, digits: int = 3) -> str:
        if math.isnan(self.mean):
            return "-"
        return f"{self.mean:.{digits}g}" + ("" if math.isnan(self.half_width) else f" ± {self.half_width:.2g}")


@dataclass(frozen=True)
class SettingFigures:
    """One setting's figures: with CSWS, without (the reference runs of the same seeds), and the paired
    change in time loss per vehicle."""

    factors: Factors
    with_csws: dict[str, Estimate]
    without_csws: dict[str, Estimate]
    time_loss_change_s: Estimate
    excess_kmh: list[float]


def setting_figures(study: Study, rows: list[dict]) -> list[SettingFigures]:
    """Every setting's figures from the runs' rows (runs not done are left out)."""
    references = {(*(row[name] for name in TRAFFIC_FACTORS), row["seed"]): row for row in rows if row["reference"]}
    figures = []
    for factors in study.settings():
        runs = [row for row in rows if not row["reference"] and _factors(row) == factors]
        paired = [(row, references.get((*(getattr(factors, n) for n in TRAFFIC_FACTORS), row["seed"]))) for row in runs]
        paired_references = [reference for _, reference in paired if reference is not None]
        figures.append(
            SettingFigures(
                factors,
                {name: Estimate.of([row[name] for row in runs]) for name, _ in FIGURES},
                {name: Estimate.of([row[name] for row in paired_references]) for name, _ in FIGURES},
                Estimate.of(
                    [
                        row["mean_time_loss_s"] - ref["mean_time_loss_s"]
                        for row, ref in paired
                        if ref is not None and row["vehicles"] and ref["vehicles"]
                    ]
                ),
                [excess for row in runs for excess in row["entry_excess_kmh"]],
            )
        )
    return figures


def _factors(row: dict) -> Factors:
    return Factors(**{name: row[name] for name in FACTORS})


def level_text(value: object) -> str:
    """A factor's level as the tables and plots show it: floats in their shortest form."""
    return f"{value:g}" if isinstance(value, float) else str(value)


def _settings_table(study: Study, figures: list[SettingFigures]) -> list[str]:
    """The settings' table: the varying factors, then each figure with and without CSWS."""
    shown = study.varying() or ["equipped_share"]
    header = [
        *shown,
        "V_w1 with",
        "V_w1 without",
        "V_w2 with",
        "V_w2 without",
        "warnings /100 veh-km",
        "time loss change s/veh",
        "seeds",
    ]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for setting in figures:
        w, wo = setting.with_csws, setting.without_csws
        cells = [level_text(getattr(setting.factors, name)) for name in shown]
        cells += [
            w["share_vehicles_above_vw1"].text(),
            wo["share_vehicles_above_vw1"].text(),
            w["share_vehicles_above_vw2"].text(),
            wo["share_vehicles_above_vw2"].text(),
            w["warnings_per_100_vehicle_km"].text(),
            setting.time_loss_change_s.text(),
            str(w["share_vehicles_above_vw1"].seeds),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


#: The columns of the table of all runs: (row field, heading).
_RUN_COLUMNS = (
    ("key", "run"),
    ("seed", "seed"),
    *((name, name) for name in FACTORS),
    ("vehicles", "vehicles"),
    ("vehicles_equipped", "equipped"),
    ("vehicle_km", "veh-km"),
    ("entries_above_vw1", "entries > V_w1"),
    ("entries_above_vw2", "entries > V_w2"),
    ("warnings", "warnings"),
    ("mean_time_loss_s", "time loss s/veh"),
    ("status", "status"),
)


def _runs_table(rows: list[dict]) -> list[str]:
    """Every run, one line each (a reference run's CSWS factors are empty: no vehicle equipped)."""
    lines = ["| " + " | ".join(heading for _, heading in _RUN_COLUMNS) + " |", "|" + "---|" * len(_RUN_COLUMNS)]
    for row in rows:
        cells = [
            "" if row[name] is None else f"{row[name]:.4g}" if isinstance(row[name], float) else str(row[name])
            for name, _ in _RUN_COLUMNS
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def write_summary_md(
    path: Path, study: Study, rows: list[dict], figures: list[SettingFigures], plots: list[str]
) -> None:
    """Write ``summary.md``."""
    scenario = study.scenario
    what = scenario.bundled or scenario.sumocfg
    fixed = ", ".join(f"{name} {level_text(levels[0])}" for name, levels in study.levels.items() if len(levels) == 1)
    runs = study.runs()
    lines = [
        f"# Study {study.name}",
        "",
        f"Scenario {what}"
        + (f", {scenario.vehicles} vehicles" if scenario.bundled == "fleet" else "")
        + f", {scenario.end_s:g} s simulated per run; seeds {study.seeds[0]}-{study.seeds[-1]}. "
        f"{len(rows)} of {len(runs)} runs done ({len(study.settings())} settings and "
        f"{len(study.references())} without CSWS, each per seed). Fixed: {fixed or 'none'}.",
        "",
        "Shares are of the vehicles that entered at least one curve part above the part's warning speed "
        "(V_w1 level 1, V_w2 level 2, Table 1); *without* is the same fleet and seeds with no vehicle equipped. "
        "Each figure is the mean over seeds ± the half width of its 95 % confidence interval (Student's t); "
        "the change in time loss per vehicle is paired with the run of the same seed without CSWS.",
        "",
        *_settings_table(study, figures),
        "",
        *(f"![{Path(plot).stem}]({plot})" for plot in plots),
        "",
        "## All runs",
        "",
        *_runs_table(rows),
        "",
    ]
    path.write_text("\n".join(lines), encoding="utf-8")


def aggregate(study: Study, out: Path) -> Path:
    """Write ``summary.md``, the plots and ``all_runs.parquet`` of the runs done; the summary's path."""
    from .plots import write_plots

    table = read_results(out, [spec.key for spec in study.runs()])
    pq.write_table(table, out / "all_runs.parquet")
    rows = table.to_pylist()
    figures = setting_figures(study, rows)
    plots = write_plots(out / "plots", study, figures, [row for row in rows if row["reference"]])
    write_summary_md(out / "summary.md", study, rows, figures, [str(p.relative_to(out)) for p in plots])
    return out / "summary.md"
