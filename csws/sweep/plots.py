"""The study's plots (matplotlib): its figures against one factor, and the excess speed at curve entry.

``summary.png``: four panels, the share of vehicles entering a curve above V_w1 and above
V_w2, warnings per 100 vehicle-km and the change in time loss per vehicle, each against the
first factor with several levels (equipment share by default), one line per level of the
other varying factors; error bars are the 95 % intervals over seeds, the dashed lines the
same fleets without CSWS. ``excess.png``: the distribution of the speed above V_w1 at curve
entry, without CSWS and per level of that factor, all seeds pooled.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np

from .aggregate import Estimate, SettingFigures, level_text
from .study import Study

__all__ = ["write_plots"]

#: The panels of ``summary.png``: (figure name, axis label, whether the reference is shown).
_PANELS = (
    ("share_vehicles_above_vw1", "share of vehicles entering\na curve above V_w1", True),
    ("share_vehicles_above_vw2", "share of vehicles entering\na curve above V_w2", True),
    ("warnings_per_100_vehicle_km", "warnings per 100 vehicle-km\n(equipped vehicles)", False),
    ("time_loss_change_s", "change in time loss\nper vehicle, s", False),
)


def _estimate(setting: SettingFigures, name: str, with_csws: bool = True) -> Estimate:
    if name == "time_loss_change_s":
        return setting.time_loss_change_s
    return (setting.with_csws if with_csws else setting.without_csws)[name]


def write_plots(folder: Path, study: Study, figures: list[SettingFigures], references: list[dict]) -> list[Path]:
    """Write ``summary.png`` and ``excess.png`` into ``folder``; their paths."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot

    folder.mkdir(parents=True, exist_ok=True)
    varying = study.varying()
    x_factor = varying[0] if varying else "equipped_share"
    others = [name for name in varying if name != x_factor]
    levels = study.levels[x_factor]
    numeric = all(isinstance(level, float) for level in levels)
    positions = list(levels) if numeric else list(range(len(levels)))
    lines = list(itertools.product(*(study.levels[name] for name in others)))
    figure, axes = pyplot.subplots(2, 2, figsize=(10, 7), sharex=True)
    for (name, label, with_reference), axis in zip(_PANELS, axes.flat, strict=False):
        for number, line in enumerate(lines):
            settings = [
                next(
                    s
                    for s in figures
                    if getattr(s.factors, x_factor) == level
                    and all(getattr(s.factors, o) == v for o, v in zip(others, line, strict=False))
                )
                for level in levels
            ]
            text = ", ".join(f"{o} {level_text(v)}" for o, v in zip(others, line, strict=False)) or "with CSWS"
            color = f"C{number % 10}"
            _errorbars(axis, positions, [_estimate(s, name) for s in settings], color, "-o", text)
            if with_reference:
                _errorbars(
                    axis,
                    positions,
                    [_estimate(s, name, False) for s in settings],
                    color,
                    "--",
                    "without CSWS" + (f" ({text})" if others else ""),
                )
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
    for axis in axes[1]:
        axis.set_xlabel(x_factor)
        if not numeric:
            axis.set_xticks(positions, [level_text(level) for level in levels])
    axes[0][0].legend(fontsize=8)
    figure.suptitle(f"Study {study.name}: mean over {len(study.seeds)} seeds, 95 % intervals", fontsize=11)
    figure.tight_layout()
    summary = folder / "summary.png"
    figure.savefig(summary, dpi=90)
    pyplot.close(figure)
    return [summary, _excess_plot(folder / "excess.png", x_factor, figures, references, pyplot)]


def _errorbars(
    axis: Any, positions: list[float], estimates: list[Estimate], color: str, style: str, label: str
) -> None:
    means = np.array([e.mean for e in estimates])
    widths = np.nan_to_num(np.array([e.half_width for e in estimates]))
    axis.errorbar(
        positions,
        means,
        yerr=widths,
        fmt=style,
        color=color,
        capsize=3,
        label=label,
        alpha=1.0 if style != "--" else 0.6,
    )


def _excess_plot(
    path: Path, x_factor: str, figures: list[SettingFigures], references: list[dict[str, Any]], pyplot: Any
) -> Path:
    """Histogram of the excess over V_w1 at curve entry: without CSWS, and per level of ``x_factor``."""
    groups = {"without CSWS": [e for row in references for e in row["entry_excess_kmh"]]}
    for setting in figures:
        groups.setdefault(f"{x_factor} {level_text(getattr(setting.factors, x_factor))}", []).extend(setting.excess_kmh)
    everything = [e for values in groups.values() for e in values] or [0.0]
    bins = np.linspace(min(min(everything), -2.0), max(max(everything), 2.0), 40)
    figure, axis = pyplot.subplots(figsize=(8, 4))
    for number, (label, values) in enumerate(groups.items()):
        axis.hist(
            values,
            bins=bins,
            histtype="step",
            linewidth=1.5,
            color="k" if number == 0 else f"C{number - 1}",
            label=f"{label} ({len(values)} entries)",
        )
    axis.axvline(0.0, color="grey", linewidth=0.8)
    axis.set_xlabel("speed above V_w1 at curve entry, km/h (entries where a warning triggered)")
    axis.set_ylabel("entries")
    axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    pyplot.close(figure)
    return path
