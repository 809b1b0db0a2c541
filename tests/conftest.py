"""Shared test set-up: a fresh profile cache for the whole run, so no test reads fits an
earlier run (or the user's own loads) left behind; in CI (``CI`` set), hypothesis draws the
same examples every run, so that a run's verdict is the code's and not the draw's (locally
it keeps exploring new ones, and keeps the failures it finds); a real ``redis-server`` for
the tests of the Redis state store, and the ``state`` fixture that runs a test on each store."""

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


@pytest.fixture(scope="session")
def redis_server(tmp_path_factory: pytest.TempPathFactory):
    """One real ``redis-server`` for the run (:class:`redis_server.RedisServer`)."""
    from redis_server import RedisServer

    server = RedisServer(tmp_path_factory.mktemp("redis"))
    yield server
    server.stop()


@pytest.fixture
def redis_url(redis_server) -> str:
    """The URL of a Redis database emptied for the test."""
    with redis_server.client() as client:
        client.flushdb()
    return redis_server.url()


@pytest.fixture(params=["sqlite", "redis"])
def state(request: pytest.FixtureRequest, tmp_path) -> dict[str, str]:
    """The settings of each state store in turn: a SQLite file, and a Redis database."""
    if request.param == "sqlite":
        return {"state_db": str(tmp_path / "vehicles.sqlite3")}
    return {"state": request.getfixturevalue("redis_url")}
