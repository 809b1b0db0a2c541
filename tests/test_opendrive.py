"""OpenDRIVE import: exact lane curvature against the design the test wrote, netconvert's lane mapping,
robust reading and the command's errors."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from markers import marks_its_tests

from csws import cli
from csws.conformance import realroads
from csws.conformance.drive import Trace, Truth
from csws.conformance.rows import Check, Row
from csws.engine import Engine, VehicleInput
from csws.opendrive.exact import ExactLane
from csws.opendrive.geometry import geometry_poses
from csws.opendrive.importer import ImportResult, import_opendrive
from csws.opendrive.lanes import KAPPA_TOLERANCE_PER_M, lane_track
from csws.opendrive.model import Geometry, OpenDriveError
from csws.opendrive.reader import parse_opendrive, read_opendrive
from csws.opendrive.writer import RoadSpec, SectionSpec, arc, line, opendrive_text, spiral, write_opendrive
from csws.road.roadmap import RoadMap
from csws.standard import DEFAULT_WARNING_RADIUS_M, Category, Level, kmh_to_mps, warning_speed

#: The design of the truth road: line - clothoid - arc - clothoid - line, turning left.
LEAD_M, SPIRAL_M, ARC_M, RADIUS_M, LANE_WIDTH_M = 400.0, 60.0, 80.0, 150.0, 3.5
RATE = 1.0 / RADIUS_M / SPIRAL_M  # curvature change along the clothoids, 1/m^2


def truth_road(road_id: str = "1") -> RoadSpec:
    """One left-hand curve with clothoid transitions, a lane each way."""
    pieces = (
        line(LEAD_M),
        spiral(SPIRAL_M, 0.0, 1.0 / RADIUS_M),
        arc(ARC_M, RADIUS_M),
        spiral(SPIRAL_M, 1.0 / RADIUS_M, 0.0),
        line(LEAD_M),
    )
    return RoadSpec(road_id, pieces, sections=(SectionSpec(0.0, (LANE_WIDTH_M,), (LANE_WIDTH_M,)),))


def reference_curvature(s: float) -> float:
    """κ of the truth road's reference line at s, from its design."""
    entry, arc_end = LEAD_M + SPIRAL_M, LEAD_M + SPIRAL_M + ARC_M
    if s <= LEAD_M or s >= arc_end + SPIRAL_M:
        return 0.0
    if s < entry:
        return RATE * (s - LEAD_M)
    return 1.0 / RADIUS_M if s <= arc_end else RATE * (arc_end + SPIRAL_M - s)


def turned_rad(s: float) -> float:
    """The reference line's heading change from 0 to s (the integral of κ), closed form."""
    entry, arc_end = LEAD_M + SPIRAL_M, LEAD_M + SPIRAL_M + ARC_M
    first = 0.5 * RATE * min(max(s - LEAD_M, 0.0), SPIRAL_M) ** 2
    middle = min(max(s - entry, 0.0), ARC_M) / RADIUS_M
    remaining = min(max(arc_end + SPIRAL_M - s, 0.0), SPIRAL_M)
    last = 0.5 * RATE * (SPIRAL_M**2 - remaining**2) if s > arc_end else 0.0
    return first + middle + last


def lane_sigma(s: float, offset_m: float) -> float:
    """Arc length of the lane at constant offset t from 0 to s: ∫(1 − κt) ds = s − t·turned(s)."""
    return s - offset_m * turned_rad(s)


def crossings(offset_m: float, warning_radius_m: float) -> tuple[float, float]:
    """Road positions s where the lane's |κ / (1 − κt)| reaches 1/R_c: κ = 1 / (R_c + t) on each clothoid."""
    kappa = 1.0 / (warning_radius_m + offset_m)
    start = LEAD_M + kappa / RATE
    end = LEAD_M + SPIRAL_M + ARC_M + (1.0 / RADIUS_M - kappa) / RATE
    return start, end


def parts_crossings(lane: ExactLane, warning_radius_m: float) -> list[float]:
    """σ where |κ| of an exact lane's linear parts crosses 1/R_c."""
    target, found = 1.0 / warning_radius_m, []
    for a, b, k0, k1 in zip(lane.bounds[:-1], lane.bounds[1:], lane.start_curvature, lane.end_curvature, strict=True):
        m0, m1 = abs(k0) - target, abs(k1) - target
        if m0 * m1 < 0:
            found.append(a + (b - a) * m0 / (m0 - m1))
    return found


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def truth_import(tmp_path_factory) -> ImportResult:
    folder = tmp_path_factory.mktemp("xodr")
    source = write_opendrive(folder / "truth.xodr", [truth_road()])
    return import_opendrive(source, folder / "truth.net.xml.gz")


def _lane(result: ImportResult, opendrive_lane: int) -> ExactLane:
    from csws.opendrive.exact import read_exact

    lanes = [lane for lane in read_exact(result.exact_path).values() if lane.opendrive_lane == opendrive_lane]
    assert len(lanes) == 1
    return lanes[0]


def test_curve_start_and_end_where_lane_curvature_crosses_the_warning_radius(truth_import: ImportResult) -> None:
    """3.4 / 3.5: on the right lane (t = -1.75 m, driven along s) |κ| reaches 1/R_c where the design says, to 1 cm."""
    lane = _lane(truth_import, -1)
    offset = -LANE_WIDTH_M / 2
    assert lane.along_s
    start_s, end_s = crossings(offset, DEFAULT_WARNING_RADIUS_M)
    found = parts_crossings(lane, DEFAULT_WARNING_RADIUS_M)
    assert len(found) == 2
    assert found[0] == pytest.approx(lane_sigma(start_s, offset), abs=0.01)
    assert found[1] == pytest.approx(lane_sigma(end_s, offset), abs=0.01)
    assert lane.length_m == pytest.approx(lane_sigma(truth_road().length_m, offset), abs=0.01)


def test_inner_and_outer_lanes_get_their_own_radii(truth_import: ImportResult) -> None:
    """The arc's radius on each lane is R ∓ t to 1 mm: the left lane (driven against s, turning right) is inner."""
    for opendrive_lane, radius_m, sign in ((-1, RADIUS_M + LANE_WIDTH_M / 2, 1), (1, RADIUS_M - LANE_WIDTH_M / 2, -1)):
        lane = _lane(truth_import, opendrive_lane)
        tightest = int(np.argmax(np.abs(lane.start_curvature)))
        assert lane.start_curvature[tightest] == lane.end_curvature[tightest]
        assert 1.0 / abs(lane.start_curvature[tightest]) == pytest.approx(radius_m, abs=0.001)
        assert math.copysign(1.0, lane.start_curvature[tightest]) == sign
        arc_length = lane.bounds[tightest + 1] - lane.bounds[tightest]
        assert arc_length == pytest.approx(ARC_M * radius_m / RADIUS_M, abs=0.01)


def test_lanes_map_to_the_sumo_lanes_netconvert_made(truth_import: ImportResult) -> None:
    """Both lanes of the road are mapped, their directions as right-hand traffic drives them."""
    from csws.opendrive.exact import read_exact

    lanes = read_exact(truth_import.exact_path)
    assert truth_import.exact_lanes == 2
    assert {(lane.road_id, lane.opendrive_lane, lane.along_s) for lane in lanes.values()} == {
        ("1", -1, True),
        ("1", 1, False),
    }


def test_the_road_map_reads_the_exact_profile(truth_import: ImportResult) -> None:
    """The curve index of the imported network has the design's curve ends (to 1 cm) and radius (to 1 mm)."""
    road_map = RoadMap.load(truth_import.net_path, cache=False)
    offset = -LANE_WIDTH_M / 2
    (curve,) = [lane_curve.curve for lane_curve in road_map.lane_curves("-1_0")]
    start_s, end_s = crossings(offset, DEFAULT_WARNING_RADIUS_M)
    assert curve.start_s == pytest.approx(lane_sigma(start_s, offset), abs=0.01)
    assert curve.end_s == pytest.approx(lane_sigma(end_s, offset), abs=0.01)
    assert curve.min_radius_m == pytest.approx(RADIUS_M - offset, abs=0.001)


def _drive(road_map: RoadMap, category: Category, speed_kmh: float) -> Trace:
    """A vehicle at constant speed along the right lane, one answer every 0.1 s."""
    engine = Engine(road_map)
    lane = road_map.lane("-1_0")
    shape = road_map.lane_shape("-1_0")
    factor = lane.length_m / float(np.hypot(*np.diff(shape, axis=0).T).sum())
    step_s = 0.1
    time_s = np.arange(0.0, lane.length_m / factor / kmh_to_mps(speed_kmh), step_s)
    route_s = kmh_to_mps(speed_kmh) * time_s
    levels = [
        int(engine.evaluate(VehicleInput("v", str(category), speed_kmh, "-1_0", s * factor, ("-1",), t)).level)
        for s, t in zip(route_s.tolist(), time_s.tolist(), strict=True)
    ]
    return Trace(0, 0.0, time_s, route_s, np.full(len(time_s), speed_kmh), np.array(levels))


@pytest.mark.parametrize("category", [Category.M1, Category.N])
@pytest.mark.parametrize("excess", [False, True])
def test_the_warning_on_the_exact_network_passes_the_real_road_judge(
    truth_import: ImportResult, monkeypatch, category: Category, excess: bool
) -> None:
    """The real-road judge, formula (1) at every design point of the curve, holds for the warning on the
    imported network: between the level-1 and level-2 V_w of its radius, and 8 km/h above the level-2 one."""
    offset = -LANE_WIDTH_M / 2
    start_s, end_s = crossings(offset, DEFAULT_WARNING_RADIUS_M)
    s = np.append(np.arange(start_s, end_s, realroads.POINT_SPACING_M), end_s)
    kappa = np.array([reference_curvature(value) for value in s.tolist()])
    points = (np.array([lane_sigma(value, offset) for value in s.tolist()]), (1 - kappa * offset) / kappa)
    monkeypatch.setattr(realroads, "_curve_points", lambda track: points)
    radius_m = RADIUS_M - offset
    level1, level2 = (warning_speed(radius_m, category, level) for level in (1, 2))
    speed_kmh = round(level2 + realroads.LEVEL2_EXCESS_KMH, 1) if excess else round((level1 + level2) / 2, 1)
    checks = tuple(Check(1, level, None, f"level {int(level)}") for level in (Level.LEVEL_1, Level.LEVEL_2))
    row = Row("xodr", realroads.REAL_ROAD_TABLE, "6.1", category, None, (radius_m,), speed_kmh, None, None, checks, ())
    truth = Truth("xodr", (lane_sigma(start_s, offset),), (lane_sigma(end_s, offset),), {"-1_0": 0.0}, ("-1",))
    trace = _drive(RoadMap.load(truth_import.net_path), category, speed_kmh)
    result = realroads.judge_real_road_run(row, trace, truth)
    assert result.passed, result
    assert trace.level.max() == (2 if excess else 1)


@pytest.mark.sumo
def test_grade_and_superelevation_reach_the_curve_index(tmp_path: Path) -> None:
    """A road rising 4 % whose cross section falls 0.05 rad to its left: along s the left curve climbs 4 % banked
    tan(0.05) toward its inside; against s it falls 4 %, and turning right it is banked toward its inside too."""
    from csws.road.export import curve_features

    spec = dataclasses.replace(truth_road("g"), grade=0.04, superelevation_rad=-0.05)
    result = import_opendrive(write_opendrive(tmp_path / "g.xodr", [spec]), tmp_path / "g.net.xml")
    features = {f["properties"]["lane_id"]: f["properties"] for f in curve_features(RoadMap.load(result.net_path))}
    assert features["-g_0"]["grade_pct"] == pytest.approx(4.0, abs=1e-9)
    assert features["g_0"]["grade_pct"] == pytest.approx(-4.0, abs=1e-9)
    for lane_id in ("-g_0", "g_0"):
        assert features[lane_id]["superelevation_pct"] == pytest.approx(100 * math.tan(0.05), abs=1e-9)


@pytest.mark.sumo
def test_the_service_serves_the_exact_curves_without_a_flag(truth_import: ImportResult) -> None:
    """``csws serve --net NET`` reads the file beside NET: /v1/curves gives the lanes' design radii R -/+ t."""
    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.settings import ServiceSettings

    served = ServiceSettings(nets=[truth_import.net_path], state_db=":memory:")
    with TestClient(create_app(served)) as client:
        features = client.get("/v1/curves").json()["features"]
    radii = {feature["properties"]["lane_id"]: feature["properties"]["radius_m"] for feature in features}
    assert radii == pytest.approx({"-1_0": RADIUS_M + LANE_WIDTH_M / 2, "1_0": RADIUS_M - LANE_WIDTH_M / 2}, abs=1e-3)
    assert all(feature["properties"]["grade_pct"] == 0.0 for feature in features)


@pytest.mark.sumo
def test_a_left_hand_road_is_mapped_as_sumo_drives_it_with_a_note(tmp_path: Path) -> None:
    """netconvert drives OpenDRIVE lanes as right-hand traffic whatever the road's rule: csws follows the SUMO
    lane (the outer lane keeps R + t along s) and notes each lane driven against the rule."""
    from csws.opendrive.exact import read_exact

    spec = dataclasses.replace(truth_road("h"), lefthand=True)
    result = import_opendrive(write_opendrive(tmp_path / "h.xodr", [spec]), tmp_path / "h.net.xml")
    lanes = read_exact(result.exact_path)
    assert lanes["-h_0"].along_s and not lanes["h_0"].along_s
    assert 1 / np.abs(lanes["-h_0"].start_curvature).max() == pytest.approx(RADIUS_M + LANE_WIDTH_M / 2, abs=1e-3)
    assert sum("against its traffic rule" in note for note in result.notes) == 2


@settings(max_examples=40, deadline=None)
@given(
    radius_m=st.floats(30.0, 450.0),
    turn=st.sampled_from([-1.0, 1.0]),
    widths=st.lists(st.floats(2.5, 4.0), min_size=1, max_size=3),
)
def test_lane_on_an_arc_has_the_offset_radius(radius_m: float, turn: float, widths: list[float]) -> None:
    """On an arc of radius R, the lane whose centre is at offset t has curvature κ / (1 − κt) exactly."""
    spec = RoadSpec("a", (arc(40.0, turn * radius_m),), sections=(SectionSpec(0.0, tuple(widths), tuple(widths)),))
    road = parse_opendrive(opendrive_text([spec])).roads[0]
    kappa = turn / radius_m
    for side in (1, -1):
        for number in range(1, len(widths) + 1):
            offset = side * (sum(widths[: number - 1]) + widths[number - 1] / 2)
            track = lane_track(road, road.sections[0], side * number)
            assert len(track.start_curvature) == 1
            assert track.start_curvature[0] == pytest.approx(kappa / (1 - kappa * offset), rel=1e-12)
            assert track.bounds[-1] == pytest.approx(40.0 * (1 - kappa * offset), rel=1e-9)


@settings(max_examples=15, deadline=None)
@given(
    length_m=st.floats(20.0, 150.0),
    start_curvature=st.floats(-1 / 30, 1 / 30),
    end_curvature=st.floats(-1 / 30, 1 / 30),
    lane=st.sampled_from([-2, -1, 1, 2]),
)
def test_lane_on_a_clothoid_stays_within_the_tolerance(
    length_m: float, start_curvature: float, end_curvature: float, lane: int
) -> None:
    """On a clothoid the lane's linear parts stay within the tolerance of κ/(1 − κt) at the reference positions,
    with not many more parts than linear interpolation needs."""
    spec = RoadSpec(
        "c", (spiral(length_m, start_curvature, end_curvature),), sections=(SectionSpec(0.0, (3.0, 3.5), (3.0, 3.5)),)
    )
    road = parse_opendrive(opendrive_text([spec])).roads[0]
    offset = math.copysign(3.0 if abs(lane) == 2 else 0.0, lane) + math.copysign(
        3.0 / 2 if abs(lane) == 1 else 3.5 / 2, lane
    )
    track = lane_track(road, road.sections[0], lane)
    rate = (end_curvature - start_curvature) / length_m
    s = np.linspace(0.0, length_m, 2001)
    kappa = start_curvature + rate * s
    sigma = s - offset * (start_curvature * s + 0.5 * rate * s**2)
    truth = kappa / (1 - kappa * offset)
    part = np.clip(np.searchsorted(track.bounds, sigma, side="right") - 1, 0, len(track.bounds) - 2)
    fraction = (sigma - track.bounds[part]) / (track.bounds[part + 1] - track.bounds[part])
    linear = track.start_curvature[part] + (track.end_curvature[part] - track.start_curvature[part]) * fraction
    assert np.max(np.abs(linear - truth)) <= 2 * KAPPA_TOLERANCE_PER_M
    assert track.bounds[-1] == pytest.approx(sigma[-1], abs=1e-4)
    # Linear interpolation errs by h²|κ''|/8: the fewest parts within the tolerance are ∫√(|κ''|/8·tol) dσ.
    bend = np.abs(np.gradient(np.gradient(truth, sigma), sigma))
    fewest = float(np.sum(np.sqrt(bend[1:] / (8 * KAPPA_TOLERANCE_PER_M)) * np.diff(sigma)))
    assert len(track.start_curvature) <= 2 * fewest + 2


def test_poly3_curvature_is_that_of_its_parabola() -> None:
    """A poly3 v = c u² has κ = 2c / (1 + (2cu)²)^(3/2) at local x u; the sampled κ matches it."""
    c = 0.004
    geometry = Geometry(0.0, 0.0, 0.0, 0.0, 50.0, "poly3", (("a", 0.0), ("b", 0.0), ("c", c), ("d", 0.0)))
    poses = geometry_poses(geometry)
    u = poses.x  # heading 0 at the start: local x is world x
    assert np.allclose(poses.curvature, 2 * c / (1 + (2 * c * u) ** 2) ** 1.5, atol=1e-12)
    assert poses.s[-1] == pytest.approx(50.0, abs=1e-4)
    assert poses.y[-1] == pytest.approx(c * u[-1] ** 2, abs=1e-9)


def test_param_poly3_of_the_same_parabola_has_the_same_curvature() -> None:
    """paramPoly3 u = X p, v = c X² p² (p normalised to [0, 1]) is the parabola v = c u² for u in [0, X]."""
    c, reach = 0.004, 45.0
    parabola = Geometry(0.0, 0.0, 0.0, 0.0, 50.0, "poly3", (("a", 0.0), ("b", 0.0), ("c", c), ("d", 0.0)))
    params = {"aU": 0.0, "bU": reach, "cU": 0.0, "dU": 0.0, "aV": 0.0, "bV": 0.0, "cV": c * reach**2, "dV": 0.0}
    parametric = Geometry(0.0, 0.0, 0.0, 0.3, 60.0, "paramPoly3", (*params.items(), ("pRange", 0.0)))
    poses = geometry_poses(parametric)
    local_x = np.cos(0.3) * poses.x + np.sin(0.3) * poses.y  # the heading of 0.3 rad turned back
    assert np.allclose(poses.curvature, 2 * c / (1 + (2 * c * local_x) ** 2) ** 1.5, atol=1e-12)
    arc_to_reach = float(np.interp(reach, geometry_poses(parabola).x, geometry_poses(parabola).s))
    assert poses.s[-1] == pytest.approx(arc_to_reach, abs=1e-3)


def _xodr(plan_view: str, extra: str = "") -> str:
    lanes = (
        '<lanes><laneSection s="0"><center><lane id="0" type="none"/></center>'
        '<right><lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>'
        "</laneSection></lanes>"
    )
    road = f'<road id="r9" length="100"><planView>{plan_view}</planView>{extra}{lanes}</road>'
    return f"<OpenDRIVE><header/>{road}</OpenDRIVE>"


def test_unknown_elements_are_skipped_with_a_note() -> None:
    text = _xodr('<geometry s="0" x="0" y="0" hdg="0" length="100"><line/><wiggle/></geometry>', "<hovercraft/>")
    read = parse_opendrive(text)
    assert len(read.roads) == 1
    assert any("r9" in note and "<hovercraft>" in note for note in read.notes)
    assert any("r9" in note and "<wiggle>" in note for note in read.notes)


def test_gaps_and_inconsistent_spiral_lengths_are_reported_with_the_road() -> None:
    """A spiral that is 40 m long but followed at s = 50, 2 cm off its end: both reported with the road id."""
    first = Geometry(0.0, 0.0, 0.0, 0.0, 40.0, "spiral", (("curvStart", 0.0), ("curvEnd", 0.01)))
    end = geometry_poses(first)
    plan = (
        '<geometry s="0" x="0" y="0" hdg="0" length="40"><spiral curvStart="0" curvEnd="0.01"/></geometry>'
        f'<geometry s="50" x="{end.x[-1] + 0.02}" y="{end.y[-1]}" hdg="{end.hdg[-1]}" length="50">'
        '<arc curvature="0.01"/></geometry>'
    )
    notes = parse_opendrive(_xodr(plan)).notes
    assert any("road r9" in note and "inconsistent length" in note for note in notes)
    assert any("road r9" in note and "0.020 m from the next" in note for note in notes)
    joined = plan.replace(f'x="{end.x[-1] + 0.02}"', f'x="{end.x[-1]}"').replace('s="50"', 's="40"')
    assert parse_opendrive(_xodr(joined)).notes == ()


@pytest.mark.parametrize(
    "content",
    [b"<OpenDRIVE><road id='1'", b"<osm/>", b"<OpenDRIVE><road id='1' length='x'><planView/></road></OpenDRIVE>"],
)
def test_malformed_file_is_one_line_and_exit_2(tmp_path: Path, capsys, content: bytes) -> None:
    source = tmp_path / "bad.xodr"
    source.write_bytes(content)
    assert cli.main(["import-opendrive", str(source), "-o", str(tmp_path / "bad.net.xml")]) == cli.EXIT_BAD_INPUT
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1
    assert "bad.xodr" in error
    with pytest.raises(OpenDriveError):
        read_opendrive(source)
