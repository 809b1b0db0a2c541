"""Shared test set-up.

* A fresh profile cache for the whole run, so that no test reads fits an earlier run (or the
  user's own loads) left behind.
* In CI (``CI`` set), hypothesis draws the same examples every run, so that a run's verdict is
  the code's and not the draw's (locally it keeps exploring new ones, and keeps the failures it
  finds).
* A real ``redis-server`` for the tests of the Redis state store (one for the run, and one of a
  test's own to stop, hang and kill), and the ``state`` fixture that runs a test on each store.
* The side roads of tests/builders.py, netconverted once for each module that serves them.
* The markers of ``pyproject.toml`` that follow from the fixtures a test uses (see
  :func:`pytest_collection_modifyitems`); the others are set in the test modules themselves.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from builders import SIDE_X_M, build_side_roads
from hypothesis import settings
from redis_server import RedisServer

settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

#: Fixtures that start a real ``redis-server``: a test that uses one is marked ``redis``.
REDIS_FIXTURES = frozenset({"redis_server", "own_redis"})
#: Fixtures that run netconvert: a test that uses one is marked ``sumo``.
NETCONVERT_FIXTURES = frozenset({"side_roads_net"})


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark ``redis`` and ``sumo`` the tests whose fixtures start a redis-server or run netconvert.

    Read from the fixtures rather than written on the tests because the ``state`` fixture is
    parametrized: only its ``redis`` instance needs a redis-server, which neither a decorator nor a
    module's ``pytestmark`` can say; and a fixture of conftest.py is used from several modules.
    """
    for item in items:
        used = set(getattr(item, "fixturenames", ()))
        params = getattr(getattr(item, "callspec", None), "params", {})
        if used & REDIS_FIXTURES or params.get("state") == "redis":
            item.add_marker(pytest.mark.redis)
        if used & NETCONVERT_FIXTURES:
            item.add_marker(pytest.mark.sumo)


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
    server = RedisServer(tmp_path_factory.mktemp("redis"))
    yield server
    server.stop()


@pytest.fixture
def redis_url(redis_server: RedisServer) -> str:
    """The URL of a Redis database emptied for the test."""
    with redis_server.client() as client:
        client.flushdb()
    return redis_server.url()


@pytest.fixture
def own_redis(tmp_path: Path):
    """A ``redis-server`` of the test's own, to be stopped, hung and killed."""
    server = RedisServer(tmp_path)
    yield server
    server.stop()


@pytest.fixture(params=["sqlite", "redis"])
def state(request: pytest.FixtureRequest, tmp_path: Path) -> dict[str, str]:
    """The settings of each state store in turn: a SQLite file, and a Redis database."""
    if request.param == "sqlite":
        return {"state_db": str(tmp_path / "vehicles.sqlite3")}
    return {"state": request.getfixturevalue("redis_url")}


@pytest.fixture(scope="module")
def side_roads_net(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The side roads (:func:`builders.build_side_roads`) placed ``SIDE_X_M`` east of the Table 7 track."""
    return build_side_roads(tmp_path_factory.mktemp("side-roads"), origin_x_m=SIDE_X_M)
