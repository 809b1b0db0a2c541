"""The rows of the benchmarks' table: a figure, its value, its target and the verdict; and the
table that ``python -m benchmarks`` and each ``python -m benchmarks.<name>`` print of them."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Row:
    """One figure of the table.

    Attributes
    ----------
    figure
        What is measured, with its unit.
    value
        The measured value (text when the figure could not be measured).
    target
        The target, e.g. ``<= 50``; empty for figures shown for context.
    passed
        Whether the value meets the target; None without one.
    baseline
        What the value is compared with, measured in the same run.
    """

    figure: str
    value: float | int | str
    target: str = ""
    passed: bool | None = None
    baseline: str = ""

    @property
    def verdict(self) -> str:
        """PASS, FAIL, or nothing for a figure without a target."""
        return {True: "PASS", False: "FAIL", None: ""}[self.passed]


def at_most(figure: str, value: float, limit: float, baseline: str = "") -> Row:
    """A figure whose target is an upper bound."""
    return Row(figure, value, f"<= {limit:g}", value <= limit, baseline)


def at_least(figure: str, value: float, limit: float, baseline: str = "") -> Row:
    """A figure whose target is a lower bound."""
    return Row(figure, value, f">= {limit:g}", value >= limit, baseline)


def context(figure: str, value: float | int | str, baseline: str = "") -> Row:
    """A figure shown for context, without a target."""
    return Row(figure, value, baseline=baseline)


def _text(value: float | int | str) -> str:
    """A value as a table cell: three significant digits, thousands separated."""
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1000 else f"{value:,.0f}"
    return f"{value:,}" if isinstance(value, int) else str(value)


def table(rows: list[Row]) -> str:
    """The rows as a fixed-width table."""
    header = ("figure", "value", "target", "", "baseline (same run)")
    cells = [header] + [(r.figure, _text(r.value), r.target, r.verdict, r.baseline) for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(4)]
    lines = [
        f"{c[0]:<{widths[0]}}  {c[1]:>{widths[1]}}  {c[2]:<{widths[2]}}  {c[3]:<{widths[3]}}  {c[4]}".rstrip()
        for c in cells
    ]
    lines.insert(1, "-" * max(map(len, lines)))
    return "\n".join(lines)
