"""Markers that a fixture hands on to every test that uses it, directly or through other fixtures.

pytest applies no marks written on fixtures, so a fixture that starts a server, runs SUMO or
netconvert, or drives a browser says so with :func:`marks_its_tests`, and conftest.py's
``pytest_collection_modifyitems`` marks each test whose fixtures say so (:func:`fixture_markers`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import pytest

FixtureFunction = TypeVar("FixtureFunction", bound=Callable)

#: The attribute of a fixture function that lists the markers it hands on.
ATTRIBUTE = "test_markers"


def marks_its_tests(*names: str) -> Callable[[FixtureFunction], FixtureFunction]:
    """Decorate a fixture function (below ``@pytest.fixture``) so that its tests get the markers ``names``."""

    def mark(fixture_function: FixtureFunction) -> FixtureFunction:
        setattr(fixture_function, ATTRIBUTE, names)
        return fixture_function

    return mark


def fixture_markers(item: pytest.Item) -> set[str]:
    """The markers that the fixtures of ``item`` hand on, through every fixture it uses."""
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return set()
    return {
        name
        for fixturedefs in info.name2fixturedefs.values()
        if fixturedefs
        for name in getattr(fixturedefs[-1].func, ATTRIBUTE, ())
    }
