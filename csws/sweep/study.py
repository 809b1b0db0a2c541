"""A study: one scenario, its factors and their levels, seeds and end time, read from TOML.

Every combination of the factors' levels is a *setting*; each setting runs once per seed.
For each seed and each setting of the factors that shape the traffic (category mix, step
length) the study also runs the fleet once without CSWS (no vehicle equipped): the
reference each setting is compared with, seed by seed.

Every value is checked before anything runs; a bad one raises :class:`StudyError`, one
line that names the file and the field (``study.toml: factors.equipped_share: 1.5 is not a
share in [0, 1]``).
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import math
import tomllib
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from csws.cli.argtypes import step_length
from csws.errors import CswsError
from csws.standard import Category

__all__ = [
    "StudyError",
    "ScenarioSpec",
    "Factors",
    "RunSpec",
    "Study",
    "read_study",
    "RESULT_FORMAT",
    "FACTORS",
    "OWN_MIX",
]

#: Part of every run's key: a change of what a run's result holds gives new keys.
RESULT_FORMAT = "csws-sweep-run/1"
#: The bundled scenarios a study can name.
BUNDLED = ("fleet", "badhersfeld")
#: The factors of a study, in the order of the summary's columns, with their defaults.
FACTORS = {
    "equipped_share": 1.0,
    "compliance_share": 1.0,
    "reaction_s": 0.8,
    "decel_mps2": 4.9,
    "step_length_s": 0.1,
    "category_mix": "scenario",
}
#: Factors that shape the traffic itself: the reference run without CSWS shares them.
TRAFFIC_FACTORS = ("step_length_s", "category_mix")
#: The level of ``category_mix`` that keeps the scenario's own vehicles.
OWN_MIX = "scenario"


class StudyError(ValueError, CswsError):
    """A study file that cannot run: one line naming the file and the field."""


@dataclass(frozen=True)
class ScenarioSpec:
    """What every run of a study simulates.

    Attributes
    ----------
    bundled
        ``fleet`` or ``badhersfeld``, or None with ``sumocfg``.
    sumocfg
        A SUMO configuration (absolute), or None.
    vehicles
        The fleet scenario's vehicles per run (one departs per second).
    end_s
        Simulated time of every run, s.
    mixes
        The category mixes the study names: name -> ((category, share), ...).
    """

    bundled: str | None
    sumocfg: str | None
    vehicles: int
    end_s: float
    mixes: tuple[tuple[str, tuple[tuple[str, float], ...]], ...] = ()

    def mix(self, name: str) -> dict[str, float] | None:
        """The category shares of the mix ``name``; None for the scenario's own."""
        return dict(dict(self.mixes)[name]) if name != OWN_MIX else None


@dataclass(frozen=True)
class Factors:
    """The levels of one run (see :data:`FACTORS`); the CSWS ones are None in a reference run."""

    equipped_share: float | None
    compliance_share: float | None
    reaction_s: float | None
    decel_mps2: float | None
    step_length_s: float
    category_mix: str


@dataclass(frozen=True)
class RunSpec:
    """One run: the scenario, its factors' levels and its seed.

    ``reference`` runs have no vehicle equipped (the fleet without CSWS).
    """

    scenario: ScenarioSpec
    factors: Factors
    seed: int

    @property
    def reference(self) -> bool:
        return self.factors.equipped_share is None

    @property
    def key(self) -> str:
        """A hash of everything that decides the run's result: its file name, how a resumed sweep knows it is done."""
        # The run's own category mix, not every mix the study names: naming another leaves it done.
        scenario = {**asdict(self.scenario), "mixes": self.scenario.mix(self.factors.category_mix)}
        text = json.dumps([RESULT_FORMAT, scenario, asdict(self.factors), self.seed], sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Study:
    """A parsed study: its runs, settings first then references, each seed by seed."""

    name: str
    scenario: ScenarioSpec
    levels: dict[str, tuple]
    seeds: tuple[int, ...]

    def settings(self) -> list[Factors]:
        """Every combination of the factors' levels."""
        return [
            Factors(**dict(zip(self.levels, values, strict=False)))
            for values in itertools.product(*self.levels.values())
        ]

    def references(self) -> list[Factors]:
        """One setting without CSWS per combination of the traffic factors' levels."""
        traffic = itertools.product(*(self.levels[name] for name in TRAFFIC_FACTORS))
        return [Factors(None, None, None, None, *values) for values in traffic]

    def runs(self) -> list[RunSpec]:
        """Every run of the study."""
        return [
            RunSpec(self.scenario, factors, seed)
            for factors in self.settings() + self.references()
            for seed in self.seeds
        ]

    def varying(self) -> list[str]:
        """The factors with more than one level."""
        return [name for name, levels in self.levels.items() if len(levels) > 1]


# ------------------------------------------------------------------ checks of single values
def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{value!r} is not a finite number")
    return float(value)


def _share(value: Any) -> float:
    share = _number(value)
    if not 0.0 <= share <= 1.0:
        raise ValueError(f"{value!r} is not a share in [0, 1]")
    return share


def _positive(value: Any) -> float:
    number = _number(value)
    if number <= 0:
        raise ValueError(f"{value!r} is not above 0")
    return number


def _not_negative(value: Any) -> float:
    number = _number(value)
    if number < 0:
        raise ValueError(f"{value!r} is below 0")
    return number


def _count(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"{value!r} is not a whole number of at least 1")
    return value


def _seed(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2**31 - 1:
        raise ValueError(f"{value!r} is not a whole number in [0, 2^31)")
    return value


def _step_length(value: Any) -> float:
    try:
        return step_length(repr(_number(value)))
    except argparse.ArgumentTypeError as exc:
        raise ValueError(str(exc)) from None


def _mix_name(value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise ValueError(f"{value!r} is not the name of a category mix")
    return value


_FACTOR_CHECKS: dict[str, Callable[[Any], Any]] = {
    "equipped_share": _share,
    "compliance_share": _share,
    "reaction_s": _not_negative,
    "decel_mps2": _positive,
    "step_length_s": _step_length,
    "category_mix": _mix_name,
}


# ------------------------------------------------------------------ the file
class _Reader:
    """Reads a study's tables, raising :class:`StudyError` that names the file and the field."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, field: str, message: str) -> StudyError:
        return StudyError(f"{self.path}: {field}: {message}")

    def table(self, document: dict, name: str, known: tuple[str, ...], field: str | None = None) -> dict:
        """The table ``name`` of ``document`` (at ``field`` in the file, default ``name``), with known keys only."""
        field = field or name
        table = document.get(name, {})
        if not isinstance(table, dict):
            raise self.fail(field, "is not a table")
        for key in table:
            if key not in known:
                raise self.fail(f"{field}.{key}", f"unknown field (known: {', '.join(known)})")
        return table

    def value(self, table: dict, section: str, key: str, check: Callable[[Any], Any], default: Any = None) -> Any:
        if key not in table:
            if default is None:
                raise self.fail(f"{section}.{key}", "is missing")
            return default
        try:
            return check(table[key])
        except ValueError as exc:
            raise self.fail(f"{section}.{key}", str(exc)) from None

    def levels(self, table: dict, name: str) -> tuple:
        raw = table.get(name, FACTORS[name])
        values = raw if isinstance(raw, list) else [raw]
        if not values:
            raise self.fail(f"factors.{name}", "has no level")
        try:
            levels = tuple(_FACTOR_CHECKS[name](value) for value in values)
        except ValueError as exc:
            raise self.fail(f"factors.{name}", str(exc)) from None
        if len(set(levels)) != len(levels):
            raise self.fail(f"factors.{name}", "a level is given twice")
        return levels


def _scenario(reader: _Reader, document: dict) -> ScenarioSpec:
    """The ``[scenario]`` table with the ``[category_mixes.*]`` tables."""
    table = reader.table(document, "scenario", ("bundled", "sumocfg", "vehicles", "end_s"))
    if ("bundled" in table) == ("sumocfg" in table):
        raise reader.fail("scenario", "give either bundled (fleet or badhersfeld) or sumocfg")
    bundled, sumocfg = table.get("bundled"), None
    if bundled is not None and bundled not in BUNDLED:
        raise reader.fail("scenario.bundled", f"{bundled!r} is not one of {', '.join(BUNDLED)}")
    if "sumocfg" in table:
        path = reader.path.parent / str(table["sumocfg"])
        if not path.is_file():
            raise reader.fail("scenario.sumocfg", f"no such SUMO configuration: {path}")
        sumocfg = str(path.resolve())
    if "vehicles" in table and bundled != "fleet":
        raise reader.fail("scenario.vehicles", "only the bundled fleet scenario generates its vehicles")
    vehicles = reader.value(table, "scenario", "vehicles", _count, default=240)
    end_s = reader.value(table, "scenario", "end_s", _positive)
    return ScenarioSpec(bundled, sumocfg, vehicles, end_s, _mixes(reader, document))


def _mixes(reader: _Reader, document: dict) -> tuple:
    """The ``[category_mixes.NAME]`` tables: category -> share."""
    mixes = document.get("category_mixes", {})
    if not isinstance(mixes, dict):
        raise reader.fail("category_mixes", "is not a table")
    parsed = []
    for name, shares in mixes.items():
        field = f"category_mixes.{name}"
        if name == OWN_MIX:
            raise reader.fail(field, f"the name {OWN_MIX} is the scenario's own mix; choose another")
        shares = (
            reader.table(mixes, name, tuple(c.value for c in Category), field) if isinstance(shares, dict) else None
        )
        if not shares:
            raise reader.fail(field, "give shares per category, e.g. M1 = 0.6, N = 0.4")
        checked = tuple((c, reader.value(shares, field, c, _not_negative)) for c in sorted(shares))
        if sum(share for _, share in checked) <= 0:
            raise reader.fail(field, "the shares add up to 0")
        parsed.append((name, checked))
    return tuple(parsed)


def read_study(path: Path) -> Study:
    """Read and check a study file.

    Raises
    ------
    StudyError
        One line naming the file and the field, for anything that would not run.
    """
    reader = _Reader(path)
    try:
        document = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise StudyError(f"{path}: cannot read the study: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{path}: not TOML: {exc}") from None
    reader.table(document, "study", ("name", "seeds", "first_seed"))
    for name in document:
        if name not in ("study", "scenario", "factors", "category_mixes"):
            raise reader.fail(name, "unknown table (known: study, scenario, factors, category_mixes)")
    study = document.get("study", {})
    seeds = reader.value(study, "study", "seeds", _count)
    first_seed = reader.value(study, "study", "first_seed", _seed, default=0)
    scenario = _scenario(reader, document)
    factors = reader.table(document, "factors", tuple(FACTORS))
    levels = {name: reader.levels(factors, name) for name in FACTORS}
    mixes = dict(scenario.mixes)
    for mix in levels["category_mix"]:
        if mix != OWN_MIX and mix not in mixes:
            raise reader.fail(
                "factors.category_mix", f"{mix!r} is neither {OWN_MIX} nor a [category_mixes.{mix}] table"
            )
        if mix != OWN_MIX and scenario.bundled != "fleet":
            raise reader.fail("factors.category_mix", "only the bundled fleet scenario can change its mix")
    name = study.get("name", path.stem)
    return Study(str(name), scenario, levels, tuple(range(first_seed, first_seed + seeds)))
