"""Shared test set-up.

* A fresh profile cache for the whole run, so that no test reads fits an earlier run (or the
  user's own loads) left behind.
* In CI (``CI`` set), hypothesis draws the same examples every run, so that a run's verdict is
  the code's and not the draw's (locally it keeps exploring new ones, and keeps the failures it
  finds). No example has a deadline: timing is for the benchmarks.
* A real ``redis-server`` for the tests of the Redis state store (one for the run, and one of a
  test's own to stop, hang and kill), and the ``state`` fixture that runs a test on each store.
* The side roads of tests/builders.py, netconverted once for each module that serves them, and
  a real server of them beside the geo-referenced Table 7 track (``served_nets``, ``served_server``).
* The markers of ``pyproject.toml`` that follow from the fixtures a test uses (see
  :func:`pytest_collection_modifyitems`); a test whose own body is slow, or runs SUMO or
  netconvert, carries its marker itself.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from browsers import CHROMIUM, CHROMIUM_ARGS
from builders import SIDE_X_M, build_side_roads, write_geo_track
from hypothesis import settings
from junction_town import build_junction_town
from markers import fixture_markers, marks_its_tests
from playwright.sync_api import sync_playwright
from redis_server import RedisServer
from servers import Server

from csws.road.hmm import SequenceMatcher
from csws.road.roadmap import RoadMap

# No example has a deadline: how long a test takes is a benchmark's business, and a loaded machine must not turn
# a slow example into a failure.
settings.register_profile("local", deadline=None)
settings.register_profile("ci", derandomize=True, deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "local")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Give each test the markers its fixtures hand on (:func:`markers.marks_its_tests`).

    Read from the fixtures rather than written on every test because a fixture that starts a
    server or builds a network is shared by many tests, some in other modules, and a test needs
    what its fixtures need however it came to use them; and because the ``state`` fixture is
    parametrized: only its ``redis`` instance needs a redis-server, which no decorator can say.
    """
    for item in items:
        for name in sorted(fixture_markers(item)):
            item.add_marker(name)
        if getattr(getattr(item, "callspec", None), "params", {}).get("state") == "redis":
            item.add_marker(pytest.mark.redis)


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
@marks_its_tests("redis")
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
@marks_its_tests("redis")
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
@marks_its_tests("sumo")
def side_roads_net(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The side roads (:func:`builders.build_side_roads`) placed ``SIDE_X_M`` east of the Table 7 track."""
    return build_side_roads(tmp_path_factory.mktemp("side-roads"), origin_x_m=SIDE_X_M)


@pytest.fixture(scope="module")
def served_nets(tmp_path_factory: pytest.TempPathFactory, side_roads_net: Path) -> list[Path]:
    """The Table 7 track made geo-referenced (:func:`builders.write_geo_track`) and the side roads."""
    return [write_geo_track(tmp_path_factory.mktemp("served")), side_roads_net]


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def served_server(served_nets: list[Path], tmp_path_factory: pytest.TempPathFactory):
    """A real server (:class:`servers.Server`) of :func:`served_nets`, one per test module."""
    running = Server(served_nets, tmp_path_factory.mktemp("state") / "vehicles.sqlite3")
    yield running
    running.stop()


@pytest.fixture(scope="module")
@marks_its_tests("browser")
def browser():
    """Headless Chromium (:mod:`browsers`), one per test module."""
    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield chromium
        chromium.close()


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def town(tmp_path_factory: pytest.TempPathFactory) -> RoadMap:
    """The junction town (:mod:`junction_town`): a straight road through a junction with side streets."""
    return build_junction_town(tmp_path_factory.mktemp("town"))


@pytest.fixture(scope="module")
def matcher(town: RoadMap) -> SequenceMatcher:
    """A sequence matcher over the junction town alone."""
    return SequenceMatcher([town])
