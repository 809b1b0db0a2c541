"""Generator of the fleet network and its mixed fleet: the co-simulation's default scenario.

One two-way rural road (one lane each way, 100 km/h; a second lane would let vehicles
change into a tighter lane inside a curve) authored with :mod:`csws.geometry`,
whose curves are the standard's: the single curves of Table 3 (R = 200, 120 and 40 m)
and the multi curves of Tables 7, 8 and 9 (curve 1 joined directly to curve 2, R2 = 40 m),
separated by 400 m straights. The road is cut into one edge per curve section (edges
``f0`` ... ``f6`` forward, ``b6`` ... ``b0`` backward), the cuts lying in the middle of
the straights.

The fleet mixes the categories of GB/T 15089 through SUMO vehicle classes (passenger
cars -> M1, buses and coaches -> M3, delivery vans and lorries -> N, semi-trailers -> O)
and one type, the minibus, that declares its category with the vType parameter
``csws.category=M2``. Every type brakes at up to 5 m/s^2 so that the co-simulation's
driver-response model (4.9 m/s^2) is within its reach.

Written files (``python -m csws.networks.fleet`` rebuilds them) in ``networks/fleet_scenario/``
(a folder of its own, apart from the test tracks): ``fleet.net.xml``, ``fleet.rou.xml``
(``FLEET_VEHICLES`` vehicles) and ``fleet.sumocfg``.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from csws.cosim.categories import VCLASS_CATEGORY
from csws.data import standard_tables
from csws.geometry import Piece, arc, piece_starts_s, pose_at, sample_pieces, straight
from csws.networks.generate import ANGLE_MARGIN, PRECISION_DIGITS
from csws.sumo.netbuild import netconvert, plain_xml_text, shape_text

__all__ = [
    "FLEET_NAME",
    "FLEET_FOLDER",
    "fleet_dir",
    "FLEET_VEHICLES",
    "FLEET_PERIOD_S",
    "FleetType",
    "FLEET_TYPES",
    "section_pieces",
    "forward_edges",
    "vtype_xml",
    "types_for_mix",
    "fleet_routes_xml",
    "build_fleet_net",
    "build_fleet",
    "main",
]

#: Base name of the fleet files.
FLEET_NAME = "fleet"
#: Folder of the fleet files inside the networks folder.
FLEET_FOLDER = "fleet_scenario"
#: Vehicles in the committed route file.
FLEET_VEHICLES = 240
#: The committed fleet departs over this many seconds, s.
FLEET_PERIOD_S = 240.0
#: Straight between two curve sections, m (the edges are cut in its middle).
STRAIGHT_M = 400.0
#: Lane speed limit, m/s (100 km/h).
LANE_SPEED_MPS = 100 / 3.6
#: Lanes per direction.
LANES = 1
#: Vertex spacing of the authored shapes, m.
SAMPLE_SPACING_M = 1.0


@dataclass(frozen=True)
class FleetType:
    """A vehicle type of the fleet.

    Attributes
    ----------
    type_id
        The vType id.
    vclass
        SUMO's vehicle class (which sets the category, see ``csws.cosim.categories``).
    share
        Share of the fleet.
    max_speed_kmh
        Top speed, km/h.
    length_m
        Length, m.
    accel_mps2
        Maximum acceleration, m/s^2.
    category
        The category declared with ``csws.category``, or None to follow the class.
    """

    type_id: str
    vclass: str
    share: float
    max_speed_kmh: float
    length_m: float
    accel_mps2: float
    category: str | None = None


#: The fleet's mix.
FLEET_TYPES = (
    FleetType("car", "passenger", 0.40, 160, 4.5, 2.6),
    FleetType("minibus", "bus", 0.08, 110, 7.0, 1.6, category="M2"),
    FleetType("coach", "coach", 0.10, 100, 12.0, 1.2),
    FleetType("bus", "bus", 0.05, 90, 12.0, 1.2),
    FleetType("van", "delivery", 0.15, 120, 6.5, 2.0),
    FleetType("lorry", "truck", 0.14, 90, 10.0, 1.1),
    FleetType("semitrailer", "trailer", 0.08, 85, 16.5, 0.9),
)


def _curve_sections(tables: dict) -> list[list[Piece]]:
    """The curve sections in driving order: Table 3's singles, then Tables 7, 8 and 9's multi curves."""
    singles = {row["radius_m"]: row["min_angle_deg"] for row in tables["table3_single_curve_track"]}
    minimum_r40_deg = singles[40]
    table7 = tables["table7_multi_curve_curve1_first"]["track"]
    table8 = tables["table8_multi_curve_curve2_first_all_before_curve1"]["M1"][0]
    table9 = tables["table9_multi_curve_curve2_first_alternating"]["M1"][0]

    def multi(row: dict, first: str, second: str) -> list[Piece]:
        return [
            arc(row["R1_m"], math.degrees(row["L1_m"] / row["R1_m"]), first),
            arc(40.0, ANGLE_MARGIN * minimum_r40_deg, second),
        ]

    return [
        [arc(200.0, ANGLE_MARGIN * singles[200], "left")],
        [arc(120.0, ANGLE_MARGIN * singles[120], "right")],
        [arc(40.0, ANGLE_MARGIN * minimum_r40_deg, "left")],
        multi(table7, "right", "right"),
        multi(table8, "left", "left"),
        multi(table9, "left", "right"),
    ]


def section_pieces() -> list[list[Piece]]:
    """The road as edges: each edge a half straight, its curve section and a half straight.

    The first edge opens with a whole straight and the last ends with one; an extra
    straight edge ends the road so that vehicles leave the last curve on a straight.
    """
    half = straight(STRAIGHT_M / 2)
    sections = [[half, *curves, half] for curves in _curve_sections(standard_tables())]
    sections[0].insert(0, half)
    return sections + [[straight(STRAIGHT_M)]]


def forward_edges() -> list[str]:
    """The forward edges in driving order; the backward ones are ``b<n>`` in reverse."""
    return [f"f{index}" for index in range(len(section_pieces()))]


def _plain_xml(lanes: int = LANES) -> tuple[str, str]:
    """Plain-XML nodes and edges: one forward and one backward edge per section, ``lanes`` lanes each."""
    sections = section_pieces()
    pieces = [piece for section in sections for piece in section]
    starts = piece_starts_s(pieces)
    boundaries = np.cumsum([0] + [len(section) for section in sections])
    x, y, heading = pose_at(pieces, starts[boundaries])
    nodes = ElementTree.Element("nodes")
    for index in range(len(boundaries)):
        ElementTree.SubElement(nodes, "node", id=f"n{index}", x=f"{x[index]:.6f}", y=f"{y[index]:.6f}")
    edges = ElementTree.Element("edges")
    for index, section in enumerate(sections):
        shape, _ = sample_pieces(section, SAMPLE_SPACING_M, (x[index], y[index]), heading[index])
        common = {"numLanes": str(lanes), "speed": f"{LANE_SPEED_MPS:.6f}", "priority": "10"}
        ElementTree.SubElement(
            edges,
            "edge",
            id=f"f{index}",
            attrib={"from": f"n{index}", "to": f"n{index + 1}", **common},
            shape=shape_text(shape),
        )
        ElementTree.SubElement(
            edges,
            "edge",
            id=f"b{index}",
            attrib={"from": f"n{index + 1}", "to": f"n{index}", **common},
            shape=shape_text(shape[::-1]),
        )
    return plain_xml_text(nodes, edges)


def vtype_xml(fleet_type: FleetType) -> str:
    """The ``<vType>`` of a fleet type."""
    parameter = f'<param key="csws.category" value="{fleet_type.category}"/>' if fleet_type.category else ""
    return (
        f'<vType id="{fleet_type.type_id}" vClass="{fleet_type.vclass}" length="{fleet_type.length_m:g}" '
        f'maxSpeed="{fleet_type.max_speed_kmh / 3.6:.4f}" accel="{fleet_type.accel_mps2:g}" decel="5" '
        f'emergencyDecel="9" speedFactor="normc(1.1,0.1,0.8,1.3)">{parameter}</vType>'
    )


def backward_edges() -> list[str]:
    """The edges of the backward direction, in driving order."""
    return [f"b{edge[1:]}" for edge in reversed(forward_edges())]


def draw_types(count: int, rng: np.random.Generator, types: tuple[FleetType, ...] = FLEET_TYPES) -> list[FleetType]:
    """``count`` vehicle types drawn with the shares of ``types`` (default: the fleet mix)."""
    shares = np.array([t.share for t in types])
    return [types[i] for i in rng.choice(len(types), size=count, p=shares / shares.sum())]


def types_for_mix(category_shares: dict[str, float]) -> tuple[FleetType, ...]:
    """The fleet's types with shares that give each category (``M1``, ``M2``, ``M3``, ``N``, ``O``) its
    share of ``category_shares``; within a category the types keep their proportions.

    Raises
    ------
    ValueError
        When a category has no type in the fleet.
    """
    category = {t.type_id: t.category or VCLASS_CATEGORY[t.vclass].value for t in FLEET_TYPES}
    missing = sorted(set(category_shares) - set(category.values()))
    if missing:
        raise ValueError(f"the fleet has no type of category {', '.join(missing)}")
    category_total = {c: sum(t.share for t in FLEET_TYPES if category[t.type_id] == c) for c in category_shares}

    def share(fleet_type: FleetType) -> float:
        of = category[fleet_type.type_id]
        return category_shares[of] * fleet_type.share / category_total[of] if of in category_shares else 0.0

    return tuple(replace(t, share=share(t)) for t in FLEET_TYPES)


def fleet_routes_xml(
    count: int = FLEET_VEHICLES,
    period_s: float = FLEET_PERIOD_S,
    seed: int = 0,
    types: tuple[FleetType, ...] = FLEET_TYPES,
) -> str:
    """A route file of ``count`` vehicles of the fleet's mix departing evenly over ``period_s``.

    Vehicles alternate between the forward and the backward direction; their types are
    drawn with the shares of ``types`` (default: the fleet mix) from a generator seeded with ``seed``.
    """
    if count < 1:
        raise ValueError(f"a fleet needs at least one vehicle, got {count}")
    drawn = draw_types(count, np.random.default_rng(seed), types)
    routes = (" ".join(forward_edges()), " ".join(backward_edges()))
    lines = ["<routes>", *(vtype_xml(t) for t in FLEET_TYPES)]
    lines += [
        f'<route id="{name}" edges="{edges}"/>' for name, edges in zip(("forward", "backward"), routes, strict=False)
    ]
    for index, fleet_type in enumerate(drawn):
        depart_s = round(index * period_s / count, 1)
        lines.append(
            f'<vehicle id="{fleet_type.type_id}{index}" type="{fleet_type.type_id}" '
            f'route="{("forward", "backward")[index % 2]}" depart="{depart_s:g}" departLane="best" departSpeed="max"/>'
        )
    lines.append("</routes>")
    return "\n".join(lines) + "\n"


def sumocfg_xml(net_file: str, route_file: str) -> str:
    """A SUMO configuration of a network and a route file (paths relative to the configuration)."""
    return (
        "<configuration>\n"
        f'  <input><net-file value="{net_file}"/><route-files value="{route_file}"/></input>\n'
        '  <time><step-length value="0.1"/></time>\n'
        "</configuration>\n"
    )


def build_fleet_net(net_file: Path, lanes: int = LANES) -> Path:
    """Write the fleet network with ``lanes`` lanes each way (the benchmark uses more) into ``net_file``."""
    nodes, edges = _plain_xml(lanes)
    return netconvert(nodes, edges, net_file, ["--precision", str(PRECISION_DIGITS)])


def build_fleet(directory: Path) -> Path:
    """Write ``fleet.net.xml``, ``fleet.rou.xml`` and ``fleet.sumocfg`` into ``directory``; the configuration's path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    build_fleet_net(directory / f"{FLEET_NAME}.net.xml")
    (directory / f"{FLEET_NAME}.rou.xml").write_text(fleet_routes_xml(), encoding="utf-8")
    config = directory / f"{FLEET_NAME}.sumocfg"
    config.write_text(sumocfg_xml(f"{FLEET_NAME}.net.xml", f"{FLEET_NAME}.rou.xml"), encoding="utf-8")
    return config


def fleet_dir() -> Path:
    """The folder of the bundled fleet files."""
    return Path(__file__).parent / FLEET_FOLDER


def main() -> None:
    """``python -m csws.networks.fleet [DIR]``: rebuild the fleet files (default: the bundled folder)."""
    directory = Path(sys.argv[1]) if len(sys.argv) > 1 else fleet_dir()
    print(f"wrote {build_fleet(directory)}")


if __name__ == "__main__":
    main()
