"""One state store for every worker and replica (service.store): switches, categories and sessions,
on SQLite and on a real Redis.

Through a real ``csws serve --workers 2`` on loopback, with two keep-alive connections proven
to be served by different workers (:meth:`servers.Workers.clients`), so that every test
whose fixes alternate between them would fail if the workers kept sessions of their own.
"""

from __future__ import annotations

import threading

import pytest
from builders import FRONTAGE_OFFSET_M, LANE_WIDTH_M, SIDE_X_M
from markers import marks_its_tests
from servers import SwitchWriter, Workers

from csws.networks import networks_dir
from csws.standard import Category
from csws.state import SystemState
from service.app import create_app
from service.settings import ServiceSettings
from service.store import StoreUnavailable, VehicleSetting
from service.vehicles import TRANSACTION_ATTEMPTS

TRACK_NET = networks_dir() / "t7_left.net.xml"
#: On the Table 7 track, 15 m before curve 1 (R 120 m): level 2 of category N from 78.0 km/h.
AT_CURVE = {"category": "N", "lane_id": "curve_0", "lane_pos_m": 85.0}


def state_options(state: dict[str, str]) -> list[str]:
    """The command-line options of a ``state`` fixture's store."""
    return ["--state", state["state"]] if "state" in state else ["--state-db", state["state_db"]]


@pytest.fixture
@marks_its_tests("slow")
def workers(state, side_roads_net):
    running = Workers([TRACK_NET, side_roads_net], *state_options(state))
    yield running
    running.stop()


def _fix(vehicle_id: str, speed_kmh: float, timestamp_s: float, **where) -> dict:
    return {"vehicle_id": vehicle_id, "speed_kmh": speed_kmh, "timestamp_s": timestamp_s, **(where or AT_CURVE)}


# ------------------------------------------------------------------ through both workers
def test_a_switch_is_seen_by_every_later_request_through_both_workers(workers) -> None:
    first, second = workers.clients()
    for client in (first, second):
        assert client.post("/v1/warning", json=_fix("truck", 80.0, 1.0)).json()["state"] == "active"
    for switching, switched_on, state in ((first, False, "off"), (second, True, "active")):
        assert switching.put("/v1/vehicles/truck", json={"switched_on": switched_on}).status_code == 200
        clients = [first, second] * 10
        answers = [client.post("/v1/warning", json=_fix("truck", 80.0, 2.0)).json() for client in clients]
        assert [a["state"] for a in answers] == [state] * 20
        seen = [client.get("/v1/vehicles/truck").json()["switched_on"] for client in clients]
        assert seen == [switched_on] * 20


def test_a_vehicle_is_one_session_whichever_worker_answers(workers) -> None:
    first, second = workers.clients()
    # The release rule's memory: level 2 came at 80 km/h; at 77.5 (0.5 below V_w) the margin keeps it.
    assert first.post("/v1/warning", json=_fix("truck", 80.0, 100.0)).json()["level"] == 2
    kept = second.post("/v1/warning", json=_fix("truck", 77.5, 100.1)).json()
    assert (kept["level"], kept["target"]["held"]) == (2, True)
    assert second.post("/v1/warning", json=_fix("fresh", 77.5, 100.1)).json()["level"] == 1
    # The last accepted timestamp: a fix older than it is stale, whichever worker gets it.
    stale = first.post("/v1/warning", json=_fix("truck", 77.5, 50.0)).json()
    assert (stale["state"], stale["fault"]) == ("fault", "the input is stale")
    state = second.get("/v1/vehicles/truck").json()
    assert (state["activated"], state["last_timestamp_s"], state["lane_id"]) == (True, 100.1, "curve_0")
    # Map matching keeps to the road of the last fix: the frontage road is nearer, the main road is kept.
    main_road = {"position": {"x": SIDE_X_M + 250.0, "y": -LANE_WIDTH_M / 2}, "heading_deg": 90.0, "category": "N"}
    between = {**main_road, "position": {"x": SIDE_X_M + 300.0, "y": FRONTAGE_OFFSET_M - 4.0}}
    assert (
        first.post("/v1/warning", json=_fix("parallel", 70.0, 1.0, **main_road)).json()["matched"]["lane_id"] == "AB_0"
    )
    assert (
        second.post("/v1/warning", json=_fix("parallel", 70.0, 1.1, **between)).json()["matched"]["lane_id"] == "AB_0"
    )
    assert (
        second.post("/v1/warning", json=_fix("new", 70.0, 1.1, **between)).json()["matched"]["lane_id"] == "frontage_0"
    )


def test_concurrent_fixes_of_one_vehicle_through_both_workers_are_each_accepted_or_stale(workers) -> None:
    # Each worker gets its own rising timestamps, both at once, so that requests meet and some are
    # answered again (the deterministic tests of that are below): every fix is answered, accepted
    # or stale, none fails, and the newest fix is the last one accepted.
    clients = workers.clients()
    answers: list[list[dict]] = [[], []]

    def send(number: int) -> None:
        for step in range(50):
            timestamp_s = 1000.0 + 0.2 * step + 0.1 * number
            answers[number].append(clients[number].post("/v1/warning", json=_fix("shared", 60.0, timestamp_s)).json())

    threads = [threading.Thread(target=send, args=(number,)) for number in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=120)
    given = answers[0] + answers[1]
    assert len(given) == 100 and {(a["state"], a["fault"]) for a in given} <= {
        ("active", None),
        ("fault", "the input is stale"),
    }
    assert clients[0].get("/v1/vehicles/shared").json()["last_timestamp_s"] == 1000.0 + 0.2 * 49 + 0.1


@pytest.mark.slow
def test_a_server_killed_during_puts_loses_no_acknowledged_one(state) -> None:
    running = Workers([TRACK_NET], *state_options(state))
    writer = SwitchWriter(running.url)
    writer.wait_for(lambda w: len(w.acknowledged) >= 100)
    running.crash()
    writer.assert_stored(state)
    assert 100 <= len(writer.acknowledged) < 1000 and not writer.refused


# ------------------------------------------------------------------ requests that meet one another
@pytest.fixture
def registries(state):
    """The vehicle registries of two workers on one store."""
    made = [create_app(ServiceSettings(nets=[TRACK_NET], **state)).state.service.registry for _ in range(2)]
    yield made
    for registry in made:
        registry.store.close()


def test_work_on_a_vehicle_another_request_wrote_meanwhile_is_done_again_from_what_it_stored(registries) -> None:
    ours, theirs = registries
    seen = []

    def switch_on(vehicles, vehicle_ids):
        seen.append(vehicles.status("truck").state)
        if len(seen) == 1:  # another worker switches the vehicle off after we read it
            theirs.transact({"truck"}, lambda others, _ids: others.configure("truck", False, Category.M3))
        vehicles.configure("truck", True, None)
        return vehicles.status("truck")

    assert ours.transact({"truck"}, switch_on).state is SystemState.STANDBY
    assert seen == [SystemState.STANDBY, SystemState.OFF]
    with ours.read({"truck"}) as vehicles:
        assert vehicles.setting("truck") == VehicleSetting(True, Category.M3)


def test_a_vehicle_other_requests_keep_writing_is_a_store_fault_and_nothing_is_written(registries) -> None:
    ours, theirs = registries
    attempts = []

    def switch_off(vehicles, _vehicle_ids):
        attempts.append(1)
        theirs.transact({"bus"}, lambda others, _ids: others.configure("bus", True, Category.M3))
        vehicles.configure("bus", False, None)

    with pytest.raises(StoreUnavailable, match="changed by other requests"):
        ours.transact({"bus"}, switch_off)
    assert len(attempts) == TRANSACTION_ATTEMPTS
    with ours.read({"bus"}) as vehicles:
        assert vehicles.setting("bus") == VehicleSetting(True, Category.M3)
