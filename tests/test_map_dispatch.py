"""The live map as a dispatcher reads it, in a real browser on a real ``csws serve`` (see ``test_map.py``).

Each check reads what the page drew back from Leaflet's layers, its canvas or its DOM, and holds it against
truth computed here: the colour distances under simulated colour blindness, the scale of the view, the
service's own answers for the levels, the target curves and the time of the last fix.
"""

from __future__ import annotations

import itertools
import json
import time

import httpx
import numpy as np
import pytest
from browsers import WAIT_MS, Recorded
from builders import TRACK_NET, write_geo_track
from markers import marks_its_tests
from playwright.sync_api import Page, Route
from servers import Workers

from service.keys import Role, add_key

#: Viénot, Brettel and Mollon (1999): linear sRGB as protanopes and deuteranopes see it (and as all others do).
VISION = {
    "normal": np.eye(3),
    "protanopia": np.array([[0.11238, 0.88762, 0.0], [0.11238, 0.88762, 0.0], [0.00401, -0.00401, 1.0]]),
    "deuteranopia": np.array([[0.29275, 0.70725, 0.0], [0.29275, 0.70725, 0.0], [-0.02234, 0.02234, 1.0]]),
}
#: The least CIE76 colour difference between a vehicle's fill and any curve's colour, for every vision.
MIN_DELTA_E = 20.0
#: The curve of the t7_left track, and a truck's fix on its approach (x, y in metres).
TRACK = "t7_left"
FIX = {"category": "N", "heading_deg": 90.0, "network": TRACK}
#: The same track placed near Bad Hersfeld (lon/lat), its curve a named street.
GEO_TRACK, STREET, ROAD_TYPE = "t7_geo", "Kurvenweg", "highway.secondary"


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def server(tmp_path_factory):
    geo_net = write_geo_track(tmp_path_factory.mktemp("geo"))
    named = f'<edge id="curve" name="{STREET}" type="{ROAD_TYPE}" '
    geo_net.write_text(geo_net.read_text().replace('<edge id="curve" ', named))
    running = Workers(
        [TRACK_NET, geo_net], "--state-db", str(tmp_path_factory.mktemp("state") / "v.sqlite3"), workers=1
    )
    yield running
    running.stop()


@pytest.fixture(scope="module")
def client(server) -> httpx.Client:
    with httpx.Client(base_url=server.url, timeout=30.0) as http:
        yield http


def _lab(hex_colour: str, vision: np.ndarray) -> np.ndarray:
    """CIE L*a*b* (D65) of an sRGB colour ``#rrggbb`` as a reader of ``vision`` sees it."""
    srgb = np.array([int(hex_colour[i : i + 2], 16) / 255 for i in (1, 3, 5)])
    linear = np.clip(vision @ np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4), 0, 1)
    xyz = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]) @ linear
    relative = xyz / [0.95047, 1.0, 1.08883]  # to the D65 white
    f = np.where(relative > 216 / 24389, np.cbrt(relative), (24389 / 27 * relative + 16) / 116)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def _open(browser, server, address: str) -> Recorded:
    recorded = Recorded(browser)
    recorded.page.goto(f"{server.url}{address}")
    recorded.page.wait_for_function("() => document.body.dataset.ready === 'true'", timeout=WAIT_MS)
    return recorded


def _track_curve(client: httpx.Client) -> dict:
    """The properties of the track's one curve as the service gives them."""
    [curve] = client.get("/v1/curves", params={"network": TRACK}).json()["features"]
    return curve["properties"]


def _post(client: httpx.Client, vehicle_id: str, **fields) -> dict:
    """The answer to one fix of a truck on the track."""
    answer = client.post("/v1/warning", json={**FIX, "vehicle_id": vehicle_id, **fields})
    assert answer.status_code == 200, answer.text
    return answer.json()


def _fleet_of_every_kind(client: httpx.Client, prefix: str) -> dict[str, dict]:
    """Trucks on the track with no warning, level 1, level 2 and a fault, by id, with their latest answers. The
    level-1 truck drives towards the curve at 100 km/h until the service first answers level 1 (6.1: inside the
    level-1 warning distance, not yet inside level 2's); the level-2 truck is 15 m before the curve at that speed."""
    answers = {
        f"{prefix}-0": _post(client, f"{prefix}-0", speed_kmh=80.0, position={"x": 300.0, "y": 0.4}),
        f"{prefix}-2": _post(client, f"{prefix}-2", speed_kmh=100.0, position={"x": 985.0, "y": 0.4}),
    }
    for step, x in enumerate(range(700, 985, 5)):
        answer = _post(client, f"{prefix}-1", speed_kmh=100.0, position={"x": x, "y": 0.4}, timestamp_s=step * 0.2)
        if answer["level"]:
            break
    answers[f"{prefix}-1"] = answer
    _post(client, f"{prefix}-f", speed_kmh=50.0, position={"x": 600.0, "y": 0.4}, timestamp_s=1.0)
    answers[f"{prefix}-f"] = _post(client, f"{prefix}-f", speed_kmh=50.0, position={"x": 600.0, "y": 400.0})
    assert [answers[f"{prefix}-{k}"]["level"] for k in "012"] == [0, 1, 2]
    assert answers[f"{prefix}-f"]["state"] == "fault"
    return answers


def _wait_for(page: Page, ids) -> None:
    page.wait_for_function("ids => ids.every(id => cswsMap.vehicles.has(id))", arg=list(ids), timeout=WAIT_MS)


def test_vehicles_differ_from_every_curve_colour_and_each_level_by_shape(browser, server, client) -> None:
    answers = _fleet_of_every_kind(client, "kinds")
    recorded = _open(browser, server, f"/map?network={TRACK}")
    page = recorded.page
    _wait_for(page, answers)
    page.wait_for_function("() => cswsMap.vehicles.get('kinds-f').properties.state === 'fault'", timeout=WAIT_MS)
    curve_colours = set(page.evaluate("cswsMap.curves.getLayers().map(l => l.options.color)"))
    curve_colours |= {colour for _upper, colour in page.evaluate("cswsMap.radiusClasses")}
    drawn = page.evaluate(
        "ids => Object.fromEntries(ids.map(id => [id, (({fillColor, color, radius, weight, dashArray}) =>"
        " ({fillColor, color, radius, weight, dashArray}))(cswsMap.vehicles.get(id).options)]))",
        list(answers),
    )
    fills = {style["fillColor"] for style in page.evaluate("Object.values(cswsMap.styles)")}
    assert len(fills) == 6 and {style["fillColor"] for style in drawn.values()} <= fills
    assert not fills & curve_colours
    for fill, curve, vision in itertools.product(fills, curve_colours, VISION.values()):
        assert np.linalg.norm(_lab(fill, vision) - _lab(curve, vision)) >= MIN_DELTA_E, (fill, curve)
    # Without colour: each level larger and more thickly ringed than the one below, the fault alone dashed.
    levels = [drawn[f"kinds-{k}"] for k in "012"]
    assert [s["radius"] for s in levels] == sorted({s["radius"] for s in levels})
    assert [s["weight"] for s in levels] == sorted({s["weight"] for s in levels})
    assert drawn["kinds-f"]["dashArray"] and not any(s["dashArray"] for s in levels)
    recorded.assert_offline()


def test_curves_are_thin_at_city_scale_and_vehicles_drawn_over_them(browser, server, client) -> None:
    curve = _track_curve(client)
    on_curve = _post(
        client, "over-curve", speed_kmh=20.0, lane_id=curve["lane_id"], lane_pos_m=curve["start_pos_m"] + 30
    )
    recorded = _open(browser, server, f"/map?network={TRACK}")
    page = recorded.page
    _wait_for(page, ["over-curve"])
    city = page.evaluate("cswsMap.cityMetresPerPixel")
    weights = {}
    for zoom in (-3, 1):  # on a plane in metres a pixel is 2^-zoom m
        page.evaluate(f"cswsMap.map.setView([0, 1050], {zoom}, {{animate: false}})")
        page.wait_for_function(f"() => Math.abs(cswsMap.map.getZoom() - {zoom}) < 1e-9", timeout=WAIT_MS)
        page.wait_for_function("b => document.body.dataset.curvesBbox !== b", arg="", timeout=WAIT_MS)
        page.wait_for_function("() => cswsMap.curves.getLayers().length === 1", timeout=WAIT_MS)
        weights[2.0**-zoom > city] = page.evaluate("cswsMap.curves.getLayers()[0].options.weight")
    assert weights[True] < weights[False]
    # The curves came after the vehicle; the canvas still shows the vehicle's fill at its centre.
    page.wait_for_function("() => cswsMap.vehicles.get('over-curve').options.fillColor", timeout=WAIT_MS)
    pixel = page.evaluate(
        """async () => {
        await new Promise(done => requestAnimationFrame(() => requestAnimationFrame(done)));
        const canvas = document.querySelector('.leaflet-overlay-pane canvas');
        const box = canvas.getBoundingClientRect(), at = cswsMap.map.latLngToContainerPoint(
            cswsMap.vehicles.get('over-curve').getLatLng());
        const mapBox = cswsMap.map.getContainer().getBoundingClientRect();
        const x = (at.x + mapBox.left - box.left) * canvas.width / box.width;
        const y = (at.y + mapBox.top - box.top) * canvas.height / box.height;
        return Array.from(canvas.getContext('2d').getImageData(Math.round(x), Math.round(y), 1, 1).data);
    }"""
    )
    expected = page.evaluate(f"cswsMap.styles['active-{on_curve['level']}'].fillColor")
    assert pixel[:3] == [int(expected[i : i + 2], 16) for i in (1, 3, 5)]
    recorded.assert_offline()


def test_a_vehicle_popup_gives_street_target_curve_vw_heading_speed_and_silence(browser, server, client) -> None:
    posted_s = time.time()  # before the fixes are sent: the popup's silence counts from when they were answered
    answers = _fleet_of_every_kind(client, "popup")
    recorded = _open(browser, server, f"/map?network={TRACK}")
    page = recorded.page
    _wait_for(page, answers)
    page.click("#warned button[data-vehicle='popup-2']")  # the list selects it: its popup opens
    page.wait_for_selector(".leaflet-popup-content td[data-field='target curve']", timeout=WAIT_MS)
    cells = page.evaluate(
        "Object.fromEntries([...document.querySelectorAll('.leaflet-popup-content td')]"
        ".map(td => [td.dataset.field, td.textContent]))"
    )
    target = answers["popup-2"]["target"]
    edge_id = answers["popup-2"]["matched"]["lane_id"].rsplit("_", 1)[0]
    [road] = [r for r in client.get("/v1/roads", params={"network": TRACK}).json()["features"] if r["id"] == edge_id]
    assert cells["street"].startswith(road["properties"]["street_name"] or "(unnamed road)")
    assert cells["target curve"] == f"{target['curve_id']}, V_w {target['warning_speed_kmh']:.1f} km/h"
    assert cells["heading"].startswith(f"{FIX['heading_deg']:.0f}° (E)")
    served = {f["id"]: f["properties"] for f in client.get("/v1/fleet", params={"network": TRACK}).json()["features"]}
    assert cells["speed"] == f"{served['popup-2']['speed_kmh']:.1f} km/h"
    assert cells["category"] == "N"
    silence_s = int(cells["last fix"].split()[0])
    assert 0 <= silence_s <= time.time() - posted_s + 1
    recorded.assert_offline()


def test_a_silent_vehicle_fades_and_then_leaves_the_map(browser, server, client) -> None:
    _post(client, "silent", speed_kmh=50.0, position={"x": 500.0, "y": 0.4})
    recorded = Recorded(browser)
    page = recorded.page
    passed_s = [0.0]  # how much later than now the service's time is made to read

    def later(route: Route) -> None:
        answer = route.fetch()
        body = answer.json()
        body["generated_s"] += passed_s[0]
        route.fulfill(response=answer, body=json.dumps(body))

    page.route("**/v1/fleet?*", later)
    page.goto(f"{server.url}/map?network={TRACK}")
    _wait_for(page, ["silent"])
    fade_s, gone_s = page.evaluate("[cswsMap.fadeAfterS, cswsMap.goneAfterS]")
    answered_s = client.get("/v1/fleet", params={"network": TRACK}).json()
    answered_at_s = next(f for f in answered_s["features"] if f["id"] == "silent")["properties"]["answered_at_s"]
    assert time.time() - answered_at_s < fade_s  # heard from just now: drawn in full
    assert page.evaluate("cswsMap.vehicles.get('silent').options.fillOpacity") == 1
    passed_s[0] = fade_s + 1
    page.wait_for_function("() => cswsMap.vehicles.get('silent').options.fillOpacity < 1", timeout=WAIT_MS)
    passed_s[0] = gone_s + 1
    page.wait_for_function("() => !cswsMap.vehicles.has('silent')", timeout=WAIT_MS)
    recorded.assert_offline()


def test_the_address_restores_the_view_and_the_selected_vehicle(browser, server, client) -> None:
    [named] = [
        r for r in client.get("/v1/roads", params={"network": GEO_TRACK}).json()["features"] if r["id"] == "curve"
    ]
    assert named["properties"] == {"street_name": STREET, "road_type": ROAD_TYPE}
    _post(client, "addressed", speed_kmh=30.0, network=GEO_TRACK, lane_id="curve_0", lane_pos_m=50.0)
    first = _open(browser, server, f"/map?network={GEO_TRACK}")
    lon, lat = named["geometry"]["coordinates"][len(named["geometry"]["coordinates"]) // 2]
    first.page.evaluate(f"cswsMap.map.setView([{lat}, {lon}], 17, {{animate: false}})")
    _wait_for(first.page, ["addressed"])
    first.page.evaluate("cswsMap.select('addressed')")
    first.page.wait_for_function("() => location.hash.includes('vehicle=addressed')", timeout=WAIT_MS)
    address = first.page.evaluate("location.pathname + location.search + location.hash")
    view = first.page.evaluate("[cswsMap.map.getZoom(), cswsMap.map.getCenter()]")
    again = _open(browser, server, address)
    page = again.page
    assert page.evaluate("cswsMap.map.getZoom()") == view[0]
    centre = page.evaluate("cswsMap.map.getCenter()")
    assert (centre["lat"], centre["lng"]) == pytest.approx((view[1]["lat"], view[1]["lng"]), abs=2e-6)
    page.wait_for_selector(".leaflet-popup-content td[data-field='street']", timeout=WAIT_MS)
    assert page.evaluate("cswsMap.vehicles.get('addressed').isPopupOpen()")
    street = page.text_content(".leaflet-popup-content td[data-field='street']")
    assert street == f"{STREET} {ROAD_TYPE}"
    first.assert_offline()
    again.assert_offline()


def test_the_warned_list_holds_exactly_the_vehicles_warned_now(browser, server, client) -> None:
    answers = _fleet_of_every_kind(client, "listed")
    recorded = _open(browser, server, f"/map?network={TRACK}")
    page = recorded.page
    _wait_for(page, answers)
    page.wait_for_function("() => cswsMap.vehicles.get('listed-f').properties.state === 'fault'", timeout=WAIT_MS)
    page.wait_for_function("() => document.querySelectorAll('#warned button').length > 0", timeout=WAIT_MS)
    listed = page.evaluate("[...document.querySelectorAll('#warned button')].map(b => b.dataset.vehicle)")
    mine = {vehicle for vehicle in listed if vehicle.startswith("listed-")}
    assert mine == {vehicle for vehicle, answer in answers.items() if answer["state"] == "active" and answer["level"]}
    # Every other vehicle listed is one the service's fleet view holds warned too, and no warned one is missing.
    fleet = client.get("/v1/fleet", params={"network": TRACK}).json()
    gone_s = page.evaluate("cswsMap.goneAfterS")
    served = fleet["features"]
    warned = {f["id"] for f in served if f["properties"]["state"] == "active" and f["properties"]["level"] >= 1}
    heard = {f["id"] for f in served if fleet["generated_s"] - f["properties"]["answered_at_s"] < gone_s - 5}
    assert warned & heard <= set(listed) <= warned and len(listed) == len(set(listed))
    # Most urgent first.
    levels = [next(f["properties"]["level"] for f in served if f["id"] == v) for v in listed]
    assert levels == sorted(levels, reverse=True)
    recorded.assert_offline()


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def keyed(tmp_path_factory):
    """A service of the track with API keys for two fleets, and those keys."""
    path = tmp_path_factory.mktemp("keys") / "api-keys.json"
    made = {fleet: add_key(path, fleet, Role.ADMIN) for fleet in ("acme", "other")}
    running = Workers([TRACK_NET], "--state-db", ":memory:", "--api-keys", str(path), workers=1)
    yield running, made
    running.stop()


def test_the_key_in_the_address_survives_every_view_written_there(browser, keyed) -> None:
    server, made = keyed
    for fleet in made:
        with httpx.Client(base_url=server.url, headers={"Authorization": f"Bearer {made[fleet]}"}) as fleet_client:
            _post(fleet_client, f"{fleet}-truck", speed_kmh=80.0, position={"x": 500.0, "y": 0.4})
    recorded = _open(browser, server, f"/map?network={TRACK}#key={made['acme']}")
    page = recorded.page
    _wait_for(page, ["acme-truck"])
    page.evaluate("cswsMap.map.setView([0, 500], 0, {animate: false})")
    page.wait_for_function("() => location.hash.includes('map=0/')", timeout=WAIT_MS)
    fragment = dict(part.split("=", 1) for part in page.evaluate("location.hash.slice(1)").split("&"))
    assert fragment["key"] == made["acme"] and fragment["map"] == "0/0.0/500.0"
    again = _open(browser, server, page.evaluate("location.pathname + location.search + location.hash"))
    _wait_for(again.page, ["acme-truck"])
    assert again.page.evaluate("[...cswsMap.vehicles.keys()]") == ["acme-truck"]  # not the other fleet's
    assert again.page.evaluate("[cswsMap.map.getZoom(), cswsMap.map.getCenter().lng]") == [0, 500]
    recorded.assert_offline()
    again.assert_offline()
