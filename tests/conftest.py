"""Shared test set-up: a fresh profile cache for the whole run, so no test reads fits an
earlier run (or the user's own loads) left behind; in CI (``CI`` set), hypothesis draws the
same examples every run, so that a run's verdict is the code's and not the draw's (locally
it keeps exploring new ones, and keeps the failures it finds); the ``state`` fixture that runs
a test on each state store."""

from __future__ import annotations

import os

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="session", autouse=True)
def fresh_profile_cache(tmp_path_factory: pytest.TempPathFactory):
    """Point ``CSWS_CACHE_DIR`` (this process and the commands it starts) at an empty folder."""
    previous = os.environ.get("CSWS_CACHE_DIR")
    os.environ["CSWS_CACHE_DIR"] = str(tmp_path_factory.mktemp("profile-cache"))
    yield
    if previous is None:
        del os.environ["CSWS_CACHE_DIR"]
    else:
        os.environ["CSWS_CACHE_DIR"] = previous


@pytest.fixture(params=["sqlite"])
def state(request: pytest.FixtureRequest, tmp_path) -> dict[str, str]:
    """The settings of each state store in turn: a SQLite file."""
    return {"state_db": str(tmp_path / "vehicles.sqlite3")}
