"""Evaluating a vehicle only where a curve warning can arise gives the warnings of evaluating every one at every step.

Random fleets on constructed roads (straights and arcs of R 60-250 m, two lanes, cut into
edges at random places) and a short run of the bundled fleet are co-simulated twice, with
``--evaluate every-step`` and ``--evaluate scheduled``: ``warnings.csv`` and ``entries.csv``
must be the same bytes, over libsumo and TraCI, while the scheduled run evaluates a fraction of
the vehicle-steps (the curve schedule's own bounds: tests/test_cosim_schedule_bounds.py). The same
holds with the forward collision warning on sparse fleets whose leaders stop; its schedule's bounds
(when two vehicles can first meet, when a state can first change) are checked against motions and
Figure 2's state rule computed here.
"""

from __future__ import annotations

import csv
import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from lane_bend import lane_bend_scenario

from csws.cosim.driver import DriverSettings
from csws.cosim.fcw import FleetFcw
from csws.cosim.fcw_schedule import first_meeting_steps, steps_state_kept
from csws.cosim.run import CosimConfig, Scenario, cosimulate
from csws.fcw.settings import FcwSettings
from csws.fcw.state import ACTIVE, STANDBY, fcw_state_code
from csws.geometry import arc, sample_pieces, straight
from csws.networks import networks_dir
from csws.networks.fleet import fleet_dir, fleet_routes_xml
from csws.sumo.netbuild import netconvert, shape_text

# The benchmarks are run from the repository, not installed: import them from there.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.cosim_routes import city_routes_xml  # noqa: E402

STEP_S = 0.1
#: The bundled city.
CITY_NET = networks_dir() / "badhersfeld.net.xml.gz"
#: The roads' speed limit, m/s (90 km/h: curves of R 60-250 m then warn most vehicles).
ROAD_SPEED_MPS = 25.0


def _road_pieces(rng: random.Random) -> list:
    """Straights and arcs of R 60-250 m turning alternately left and right."""
    pieces = [straight(rng.uniform(300.0, 600.0))]
    for i in range(4):
        radius_m = rng.uniform(60.0, 250.0)
        pieces.append(arc(radius_m, rng.uniform(25.0, 80.0), "left" if i % 2 else "right"))
        pieces.append(straight(rng.uniform(150.0, 500.0)))
    return pieces


def _build_road(folder: Path, rng: random.Random, lanes: int = 2) -> tuple[Path, list[str]]:
    """A one-way road of ``lanes`` lanes and random pieces, cut into edges at random places; its net and edge ids."""
    xy, _ = sample_pieces(_road_pieces(rng), 2.0, (0.0, 0.0), 0.0)
    cuts = sorted(rng.sample(range(20, len(xy) - 20), 3))
    bounds = [0, *cuts, len(xy) - 1]
    nodes = [f'<node id="n{i}" x="{xy[b][0]:.6f}" y="{xy[b][1]:.6f}"/>' for i, b in enumerate(bounds)]
    edges = [
        f'<edge id="e{i}" from="n{i}" to="n{i + 1}" numLanes="{lanes}" speed="{ROAD_SPEED_MPS}" '
        f'shape="{shape_text(xy[a : b + 1])}"/>'
        for i, (a, b) in enumerate(zip(bounds, bounds[1:], strict=False))
    ]
    net = netconvert(
        "<nodes>" + "".join(nodes) + "</nodes>", "<edges>" + "".join(edges) + "</edges>", folder / "road.net.xml"
    )
    return net, [f"e{i}" for i in range(len(edges))]


def _fleet(folder: Path, edges: list[str], rng: random.Random, vehicles: int, blocker: str = "") -> Path:
    """A random mixed fleet on the road: cars, trucks and buses of random speed factors, departing at random
    (after ``blocker``, a vehicle element put first)."""
    types = [
        '<vType id="car" vClass="passenger" speedFactor="1.1" speedDev="0.15"/>',
        '<vType id="truck" vClass="truck" maxSpeed="25" speedFactor="1.0" speedDev="0.1"/>',
        '<vType id="bus" vClass="bus" speedFactor="0.95" speedDev="0.1"/>',
    ]
    departures = sorted(rng.uniform(0.0, 60.0) for _ in range(vehicles))
    cars = [
        f'<vehicle id="v{i}" type="{rng.choice(("car", "car", "truck", "bus"))}" route="road" '
        f'depart="{depart:.1f}" departLane="random" departSpeed="random"/>'
        for i, depart in enumerate(departures)
    ]
    path = folder / "fleet.rou.xml"
    path.write_text(
        f'<routes>{"".join(types)}<route id="road" edges="{" ".join(edges)}"/>{blocker}{"".join(cars)}</routes>',
        encoding="utf-8",
    )
    return path


def _both(scenario: Scenario, out: Path, **settings) -> tuple[Path, Path, dict]:
    """Run the scenario every step (with its time series) and scheduled; their folders, and the scheduled run's
    summary. Both give the share of vehicle-steps with a curve warning on that the time series shows, and the
    scheduled run evaluated at least those (a warned vehicle is evaluated every step)."""
    every, scheduled = out / "every", out / "scheduled"
    full = cosimulate(CosimConfig(scenario, every, evaluation="every-step", timeseries="csv", **settings))
    assert full["evaluation"]["mode"] == "every step"
    summary = cosimulate(CosimConfig(scenario, scheduled, evaluation="scheduled", timeseries="none", **settings))
    with (every / "timeseries.csv").open(encoding="utf-8", newline="") as rows:
        levels = [row["level"] for row in csv.DictReader(rows)]
    warned_share = sum(level != "0" for level in levels) / len(levels)
    assert full["evaluation"]["vehicle_steps_warned_share"] == pytest.approx(warned_share)
    assert summary["evaluation"]["vehicle_steps_warned_share"] == pytest.approx(warned_share)
    assert summary["evaluation"]["vehicle_steps_evaluated_share"] >= warned_share
    return every, scheduled, summary


def _assert_same_warnings(every: Path, scheduled: Path, summary: dict, most_evaluated: float = 0.9) -> None:
    """The two runs' warning events and entries are the same bytes; the scheduled one evaluated less (at most
    ``most_evaluated`` of the vehicle-steps)."""
    events = (every / "warnings.csv").read_bytes()
    assert events.count(b"\n") > 5, "the scenario must warn"
    assert (scheduled / "warnings.csv").read_bytes() == events
    assert (scheduled / "entries.csv").read_bytes() == (every / "entries.csv").read_bytes()
    assert summary["evaluation"]["mode"] == "scheduled"
    assert summary["evaluation"]["vehicle_steps_evaluated_share"] < most_evaluated


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.parametrize(
    ("seed", "interface", "driver"),
    [(1, "libsumo", False), (2, "libsumo", True), (3, "traci", False)],
)
def test_scheduled_runs_warn_as_every_step_runs_on_random_fleets(tmp_path, seed, interface, driver):
    rng = random.Random(seed)
    net, edges = _build_road(tmp_path, rng)
    routes = _fleet(tmp_path, edges, rng, vehicles=40)
    every, scheduled, summary = _both(
        Scenario(None, net, (routes,)),
        tmp_path,
        step_length_s=STEP_S,
        end_s=150.0,
        interface=interface,
        seed=seed,
        driver=DriverSettings() if driver else None,
    )
    _assert_same_warnings(every, scheduled, summary)


@pytest.mark.slow
@pytest.mark.sumo
def test_vehicles_teleported_out_of_a_jam_warn_as_in_every_step_runs(tmp_path):
    """A car stopped on a one-lane road for minutes holds up those behind it until SUMO teleports them
    (after 3 s of waiting) to somewhere ahead, nearer the curves: they are woken when the teleport starts."""
    rng = random.Random(5)
    net, edges = _build_road(tmp_path, rng, lanes=1)
    blocker = (
        f'<vehicle id="blocker" type="car" route="road" depart="0" departSpeed="0">'
        f'<stop lane="{edges[1]}_0" endPos="20" duration="500"/></vehicle>'
    )
    routes = _fleet(tmp_path, edges, rng, vehicles=30, blocker=blocker)
    config = tmp_path / "jam.sumocfg"
    config.write_text(
        f'<configuration><input><net-file value="{net.name}"/></input>'
        '<processing><time-to-teleport value="3"/></processing></configuration>',
        encoding="utf-8",
    )
    every, scheduled, summary = _both(
        Scenario(config, net, (routes,)), tmp_path, step_length_s=STEP_S, end_s=150.0, seed=5
    )
    _assert_same_warnings(every, scheduled, summary)


def _fork(folder: Path) -> Path:
    """A road that forks 560 m on: straight on to a junction 840 m further, or off 20 degrees to the right into a
    branch whose R 60 m curve starts 150 m after the fork (its first warning point lies before the fork) and that
    comes back to that junction; an exit road leaves it."""
    xy, _ = sample_pieces([straight(150.0), arc(60.0, 90.0, "right"), straight(100.0)], 2.0, (560.0, 0.0), -0.35)
    nodes = (
        '<nodes><node id="n0" x="0" y="0"/><node id="n1" x="500" y="0"/><node id="n2" x="560" y="0"/>'
        f'<node id="n3" x="1400" y="0"/><node id="n4" x="{xy[-1][0]:.6f}" y="{xy[-1][1]:.6f}"/>'
        '<node id="n5" x="1700" y="0"/></nodes>'
    )
    road = [("a0", "n0", "n1", ""), ("a1", "n1", "n2", ""), ("straight", "n2", "n3", ""), ("back", "n4", "n3", "")]
    road += [("branch", "n2", "n4", f' shape="{shape_text(xy)}"'), ("exit", "n3", "n5", "")]
    edges = "".join(
        f'<edge id="{edge}" from="{a}" to="{b}" speed="{ROAD_SPEED_MPS}"{shape}/>' for edge, a, b, shape in road
    )
    return netconvert(nodes, f"<edges>{edges}</edges>", folder / "fork.net.xml")


def _fork_scenario(
    folder: Path, additional: str, route: str, rerouting_device: bool = False, arrival: str = ""
) -> Scenario:
    """40 cars on the fork's road along ``route`` (edge ids), with ``additional`` elements (rerouters, speed signs),
    each car's rerouting device (every 2 s) or none, and its ``arrival`` attributes."""
    net = _fork(folder)
    cars = "".join(
        f'<vehicle id="v{i}" type="car" route="r" depart="{i * 3.7:.1f}" departSpeed="max"{arrival}/>'
        for i in range(40)
    )
    (folder / "fork.rou.xml").write_text(
        f'<routes><vType id="car" vClass="passenger" speedDev="0.1"/><route id="r" edges="{route}"/>{cars}</routes>',
        encoding="utf-8",
    )
    (folder / "fork.add.xml").write_text(f"<additional>{additional}</additional>", encoding="utf-8")
    routing = (
        '<routing><device.rerouting.probability value="1"/><device.rerouting.period value="2"/></routing>'
        if rerouting_device
        else ""
    )
    config = folder / "fork.sumocfg"
    config.write_text(
        '<configuration><input><net-file value="fork.net.xml"/><route-files value="fork.rou.xml"/>'
        f'<additional-files value="fork.add.xml"/></input>{routing}</configuration>',
        encoding="utf-8",
    )
    return Scenario(config, net, ())


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.parametrize("how", ["rerouter", "device"])
def test_vehicles_rerouted_while_asleep_warn_as_in_every_step_runs(tmp_path, how):
    """Routed straight on, the cars sleep towards the junction ahead; SUMO sends them round by the branch, whose curve
    they then near before they would wake: a rerouter before the fork that closes the straight road, or each car's
    rerouting device once a speed sign has slowed the straight road to 1 m/s. They are woken when their route
    changes."""
    if how == "rerouter":
        additional = (
            '<rerouter id="closed" edges="a1"><interval begin="0" end="100000">'
            '<closingReroute id="straight"/></interval></rerouter>'
        )
    else:
        additional = (
            '<variableSpeedSign id="slow" lanes="straight_0"><step time="0" speed="25"/><step time="30" speed="1"/>'
            "</variableSpeedSign>"
        )
    scenario = _fork_scenario(tmp_path, additional, "a0 a1 straight exit", rerouting_device=how == "device")
    every, scheduled, summary = _both(scenario, tmp_path, step_length_s=STEP_S, end_s=200.0, seed=3)
    assert b"branch" in (every / "entries.csv").read_bytes()  # the cars were warned of the branch's curve
    _assert_same_warnings(every, scheduled, summary)


@pytest.mark.slow
@pytest.mark.sumo
def test_vehicles_that_may_be_rerouted_can_arrive_asleep(tmp_path):
    """A rerouter that never acts makes every car one SUMO may reroute; past the branch's curve the cars sleep, and
    arrive 100 m into the road back, asleep: the run reads no route of a car that left."""
    idle = (
        '<rerouter id="idle" edges="exit"><interval begin="0" end="100000">'
        '<closingReroute id="straight"/></interval></rerouter>'
    )
    scenario = _fork_scenario(tmp_path, idle, "a0 a1 branch back", arrival=' arrivalPos="100"')
    every, scheduled, summary = _both(scenario, tmp_path, step_length_s=STEP_S, end_s=200.0, seed=3)
    _assert_same_warnings(every, scheduled, summary)


@pytest.mark.slow
@pytest.mark.sumo
def test_a_speed_sign_raising_the_limit_while_vehicles_sleep_keeps_the_warnings_of_every_step_runs(tmp_path):
    """A variable speed sign raises the limit of the road into the branch from 25 to 45 m/s at 5 s: the cars, faster
    than any lane allowed when they departed, are still woken in time."""
    additional = (
        '<variableSpeedSign id="faster" lanes="a0_0 a1_0 branch_0">'
        '<step time="0" speed="25"/><step time="5" speed="45"/></variableSpeedSign>'
    )
    scenario = _fork_scenario(tmp_path, additional, "a0 a1 branch back exit")
    every, scheduled, summary = _both(scenario, tmp_path, step_length_s=STEP_S, end_s=200.0, seed=3)
    _assert_same_warnings(every, scheduled, summary)


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.parametrize("interface", ["libsumo", "traci"])
def test_cars_changing_lanes_while_asleep_onto_a_lane_with_its_own_bend_warn_as_in_every_step_runs(tmp_path, interface):
    """The cars fall asleep on the right lane, whose path ends straight where it stops, and change to the left lane,
    whose bends are within their warning distance before they would wake on the right lane's path: they sleep
    towards the curves of the lanes beside their path too (csws.cosim.lanes_beside)."""
    scenario = lane_bend_scenario(tmp_path)
    every, scheduled, summary = _both(
        scenario, tmp_path, step_length_s=STEP_S, end_s=250.0, seed=3, interface=interface
    )
    with (every / "warnings.csv").open(encoding="utf-8", newline="") as rows:
        warned = {row["vehicle_id"] for row in csv.DictReader(rows) if row["lane_id"] == "b_1"}
    assert len(warned) > 20  # the cars were warned of the left lane's bends
    _assert_same_warnings(every, scheduled, summary, most_evaluated=0.5)


@pytest.mark.slow
@pytest.mark.sumo
def test_scheduled_run_of_the_bundled_fleet_warns_as_every_step(tmp_path):
    routes = tmp_path / "fleet.rou.xml"
    routes.write_text(fleet_routes_xml(60, period_s=30.0, seed=4), encoding="utf-8")
    scenario = Scenario(None, fleet_dir() / "fleet.net.xml", (routes,))
    every, scheduled, summary = _both(scenario, tmp_path, step_length_s=0.2, end_s=120.0)
    _assert_same_warnings(every, scheduled, summary)


@pytest.mark.slow
@pytest.mark.sumo
def test_scheduled_run_in_the_bundled_city_warns_as_every_step(tmp_path):
    """A real city's map, with its junctions, lanes fitted on their own and lanes that lead elsewhere: 2,000
    vehicles of the fleet's mix on random walks through Bad Hersfeld for 20 s."""
    routes = tmp_path / "city.rou.xml"
    routes.write_text(city_routes_xml(CITY_NET, 2000, seed=3), encoding="utf-8")
    every, scheduled, summary = _both(Scenario(None, CITY_NET, (routes,)), tmp_path, end_s=20.0)
    _assert_same_warnings(every, scheduled, summary, most_evaluated=0.6)


def _sparse_fleet_with_stops(folder: Path, edges: list[str], rng: random.Random, vehicles: int) -> Path:
    """Cars, trucks and mopeds departing a few seconds to half a minute apart at full speed; most trucks stop
    for a while somewhere on the road, and mopeds are caught up. Cars and trucks brake late and hard (decel
    8 m/s^2, the inattentive driver an FCW is for), so those catching up are warned."""
    types = (
        '<vType id="car" vClass="passenger" speedFactor="1.1" speedDev="0.2" decel="8" emergencyDecel="9"/>'
        '<vType id="truck" vClass="truck" maxSpeed="22" speedDev="0.1" decel="8" emergencyDecel="9"/>'
        '<vType id="moped" vClass="moped" maxSpeed="12"/>'
    )
    elements, depart_s = [], 0.0
    for i in range(vehicles):
        depart_s += rng.uniform(3.0, 30.0)
        kind = rng.choice(("car", "car", "truck", "moped"))
        stop = ""
        if kind == "truck" and rng.random() < 0.8:
            lane = f"{edges[rng.randrange(1, len(edges))]}_{rng.randrange(2)}"
            stop = f'<stop lane="{lane}" endPos="{rng.uniform(20, 80):.0f}" duration="{rng.uniform(5, 25):.0f}"/>'
        elements.append(
            f'<vehicle id="v{i}" type="{kind}" route="road" depart="{depart_s:.1f}" departLane="random" '
            f'departSpeed="max">{stop}</vehicle>'
        )
    path = folder / "sparse.rou.xml"
    path.write_text(
        f'<routes>{types}<route id="road" edges="{" ".join(edges)}"/>{"".join(elements)}</routes>', encoding="utf-8"
    )
    return path


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.parametrize(
    ("seed", "interface", "systems", "driver"),
    [
        (15, "libsumo", ("fcw",), False),
        (12, "libsumo", ("csws", "fcw"), True),
        (14, "traci", ("csws", "fcw"), False),
        (16, "traci", ("fcw",), False),
    ],
)
def test_scheduled_fcw_runs_warn_as_every_step_runs_on_random_fleets(tmp_path, seed, interface, systems, driver):
    """Leaders stopping and slow mopeds ahead of faster traffic: the forward collision warnings (and the curve
    warnings beside them) of a scheduled run are those of evaluating every vehicle at every step, to the byte."""
    rng = random.Random(seed)
    net, edges = _build_road(tmp_path, rng)
    routes = _sparse_fleet_with_stops(tmp_path, edges, rng, vehicles=24)
    every, scheduled, summary = _both(
        Scenario(None, net, (routes,)),
        tmp_path,
        step_length_s=STEP_S,
        end_s=320.0,
        interface=interface,
        seed=seed,
        systems=systems,
        driver=DriverSettings() if driver else None,
    )
    assert b"fcw_onset" in (every / "warnings.csv").read_bytes(), "the scenario must give forward collision warnings"
    # Another vehicle is within some 260 m of most vehicles most of the time: the FCW keeps them awake then.
    _assert_same_warnings(every, scheduled, summary, most_evaluated=0.95)


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.parametrize("interface", ["libsumo", "traci"])
def test_a_car_appearing_close_ahead_of_a_sleeping_fcw_subject_on_a_bend_is_seen_as_in_every_step_runs(
    tmp_path, interface, monkeypatch
):
    """A car drives alone into an R 250 m bend, its FCW asleep (nothing within reach); 24 s on, a slow car is put
    on the road 40 m ahead of it (SUMO's insertion checks off), where only the bend's path has it in the lane. The
    subject is woken at once and warned at that step, with the yaw rate of its heading read while it slept: the
    object's range along the bent path is that of the every-step run, to the byte. Without that read (the subject
    asleep at the step before) the range differs."""
    xy, _ = sample_pieces([straight(300.0), arc(250.0, 700.0, "left"), straight(300.0)], 2.0, (0.0, 0.0), 0.0)
    nodes = f'<nodes><node id="n0" x="0" y="0"/><node id="n1" x="{xy[-1][0]:.6f}" y="{xy[-1][1]:.6f}"/></nodes>'
    edges = f'<edges><edge id="r" from="n0" to="n1" speed="{ROAD_SPEED_MPS}" shape="{shape_text(xy)}"/></edges>'
    net = netconvert(nodes, edges, tmp_path / "bend.net.xml")
    appear_s = 24.0
    routes = tmp_path / "bend.rou.xml"
    routes.write_text(
        '<routes><vType id="car" vClass="passenger" speedDev="0" decel="8" emergencyDecel="9"/>'
        '<vType id="slow" vClass="passenger" maxSpeed="5" speedDev="0"/><route id="r" edges="r"/>'
        '<vehicle id="subject" type="car" route="r" depart="0" departSpeed="max"/>'
        f'<vehicle id="ahead" type="slow" route="r" depart="{appear_s}" '
        f'departPos="{ROAD_SPEED_MPS * appear_s + 40.0:.1f}" departSpeed="5" insertionChecks="none"/></routes>',
        encoding="utf-8",
    )
    scenario = Scenario(None, net, (routes,))
    settings = {"step_length_s": STEP_S, "end_s": 40.0, "interface": interface, "systems": ("fcw",)}
    every, scheduled, summary = _both(scenario, tmp_path, **settings)
    onsets = [
        row for row in csv.DictReader((every / "warnings.csv").open(encoding="utf-8")) if row["event"] == "fcw_onset"
    ]
    assert [(row["vehicle_id"], row["fcw_target_id"]) for row in onsets][:1] == [("subject", "ahead")]
    assert float(onsets[0]["time_s"]) == pytest.approx(appear_s + STEP_S)  # warned at the step it appeared
    assert (scheduled / "warnings.csv").read_bytes() == (every / "warnings.csv").read_bytes()
    assert summary["evaluation"]["vehicle_steps_evaluated_share"] < 0.8  # the subject slept before
    monkeypatch.setattr(FleetFcw, "keep_headings", lambda self, schedule: None)
    unread = tmp_path / "unread"
    cosimulate(CosimConfig(scenario, unread, evaluation="scheduled", timeseries="none", **settings))
    assert (unread / "warnings.csv").read_bytes() != (every / "warnings.csv").read_bytes()


@given(
    distance_m=st.floats(0.0, 5000.0),
    bound_mps=st.floats(0.0, 45.0),
    other_bound_mps=st.floats(0.0, 45.0),
    stale_steps=st.integers(0, 60),
    factor=st.floats(0.8, 1.0),
)
def test_two_vehicles_cannot_come_within_reach_before_their_first_meeting_step(
    distance_m, bound_mps, other_bound_mps, stale_steps, factor
):
    """The first meeting step is the first at which the two, each driving straight at the other as fast as its
    bound allows (the other from where it was read ``stale_steps`` before), could be within the reach."""
    reach_m, now = 263.0, 100
    meet = first_meeting_steps(
        np.array([distance_m]),
        reach_m,
        now,
        np.array([bound_mps]),
        np.array([other_bound_mps]),
        np.array([now - stale_steps]),
        STEP_S,
        factor,
    )[0]

    def closest_m(step: int) -> float:
        return distance_m - (bound_mps * (step - now) + other_bound_mps * (step - now + stale_steps)) * STEP_S / factor

    tolerance_m = 1e-9 * (distance_m + reach_m)
    if not math.isfinite(meet):
        # Never: no closing speed, or one so small (subnormal) that the steps to close the gap exceed any float.
        closing_m = (bound_mps + other_bound_mps) * STEP_S / factor
        assert distance_m > reach_m and (closing_m == 0.0 or not math.isfinite((distance_m - reach_m) / closing_m))
        return
    # The closest they can be falls with every step: it is above the reach until the meeting step, not after.
    meet = int(meet)
    assert meet == now or closest_m(meet - 1) > reach_m - tolerance_m
    assert closest_m(meet) <= reach_m + tolerance_m


@given(
    speed_mps=st.floats(0.0, 40.0),
    was_active=st.booleans(),
    accel_mps2=st.floats(0.5, 4.0),
    decel_mps2=st.floats(3.0, 10.0),
    category=st.sampled_from(["M1", "N", "M3"]),
)
def test_the_fcw_state_cannot_change_before_the_speed_is_read_again(
    speed_mps, was_active, accel_mps2, decel_mps2, category
):
    """4.3: from a step at ``speed_mps``, the speed rising or falling as fast as the type allows (the only ways
    it can cross a threshold) keeps the state of Figure 2 until the step the schedule reads the speed again."""
    settings = FcwSettings.for_category(category)
    state = fcw_state_code(ACTIVE if was_active else STANDBY, speed_mps, True, True, True, settings)
    steps = steps_state_kept(state, speed_mps, settings, accel_mps2, decel_mps2, STEP_S)
    assert steps >= 1
    for change_mps2 in (accel_mps2, -decel_mps2):
        now_state, now_mps = state, speed_mps
        for _ in range(1, min(steps, 2000)):
            now_mps = max(0.0, now_mps + change_mps2 * STEP_S)
            now_state = fcw_state_code(now_state, now_mps, True, True, True, settings)
            assert now_state == state
