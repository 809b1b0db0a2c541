"""A two-lane road whose left lane swerves by bends its right lane does not make: the lanes of one edge do not
share their curves (tests/test_cosim_lanes_beside.py, tests/test_cosim_schedule.py)."""

from __future__ import annotations

from pathlib import Path

from csws.cosim.run import Scenario
from csws.geometry import arc, sample_pieces, straight
from csws.sumo.netbuild import netconvert, shape_text

#: The roads' speed limit, m/s.
SPEED_MPS = 25.0
#: Where edge ``b`` starts, and how far into it the left lane's first bend starts (along its own shape), m.
B_START_M = 600.0
BEND_START_M = 300.0
#: The radius of the bends' arcs, m.
BEND_RADIUS_M = 100.0


def lane_bend_net(folder: Path) -> Path:
    """A two-lane road ``a`` (600 m) then ``b`` (1,000 m), straight, into a one-lane road ``c`` that only ``b``'s
    left lane joins. That lane has a shape of its own: :data:`BEND_START_M` into ``b`` it swerves 4 m to the left
    and back by two S-bends of R 100 m arcs (20 m each), which the right lane does not make."""
    bend = [straight(BEND_START_M), arc(BEND_RADIUS_M, 20.0, "left"), arc(BEND_RADIUS_M, 20.0, "right")]
    bend += [straight(100.0), arc(BEND_RADIUS_M, 20.0, "right"), arc(BEND_RADIUS_M, 20.0, "left")]
    # The left lane's centre is 1.6 m right of the edge's line (the lanes spread to its right).
    xy, _ = sample_pieces(bend, 2.0, (B_START_M, -1.6), 0.0)
    left_lane = [*map(tuple, xy), (B_START_M + 1000.0, -1.6)]
    nodes = "".join(f'<node id="n{i}" x="{x}" y="0"/>' for i, x in enumerate((0.0, B_START_M, B_START_M + 1000, 1900)))
    edges = (
        f'<edge id="a" from="n0" to="n1" numLanes="2" speed="{SPEED_MPS}"/>'
        f'<edge id="b" from="n1" to="n2" numLanes="2" speed="{SPEED_MPS}">'
        f'<lane index="1" shape="{shape_text(left_lane)}"/></edge>'
        f'<edge id="c" from="n2" to="n3" numLanes="1" speed="{SPEED_MPS}"/>'
    )
    connections = folder / "bend.con.xml"
    connections.write_text(
        '<connections><connection from="a" to="b" fromLane="0" toLane="0"/>'
        '<connection from="a" to="b" fromLane="1" toLane="1"/><connection from="b" to="c" fromLane="1" toLane="0"/>'
        "</connections>",
        encoding="utf-8",
    )
    return netconvert(
        f"<nodes>{nodes}</nodes>",
        f"<edges>{edges}</edges>",
        folder / "bend.net.xml",
        ["--connection-files", str(connections)],
    )


def lane_bend_scenario(folder: Path) -> Scenario:
    """40 cars on :func:`lane_bend_net` along ``a b c``, departing on the right lane at full speed 3.7 s apart: each
    must change to the left lane somewhere before ``c``, where SUMO decides."""
    cars = "".join(
        f'<vehicle id="v{i}" type="car" route="r" depart="{i * 3.7:.1f}" departLane="0" departSpeed="max"/>'
        for i in range(40)
    )
    routes = folder / "bend.rou.xml"
    routes.write_text(
        f'<routes><vType id="car" vClass="passenger" speedDev="0.1"/><route id="r" edges="a b c"/>{cars}</routes>',
        encoding="utf-8",
    )
    return Scenario(None, lane_bend_net(folder), (routes,))
