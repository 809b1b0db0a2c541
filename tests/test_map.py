"""The live map and the offline docs in a real browser: a real ``csws serve`` on loopback, headless
Chromium (the Debian package ``chromium``) driven by Playwright, every request the pages make
recorded.

What the page draws is read back from Leaflet's layers (the page draws on a canvas) and checked
against what the service answers for the same view: the curves of ``/v1/curves``, the vehicles of
``/v1/fleet``, each vehicle's colour against the state and level of its own latest answer.
"""

from __future__ import annotations

import os

import httpx
import pytest
from browsers import WAIT_MS, Recorded
from builders import TRACK_NET
from markers import marks_its_tests
from playwright.sync_api import Page
from servers import Workers

from csws.networks import networks_dir

GEO_NET = networks_dir() / "badhersfeld.net.xml.gz"
#: The most the map page of the Bad Hersfeld network may fetch before it shows its curves, bytes.
INITIAL_DATA_LIMIT_BYTES = 2_000_000
#: Vehicles fed at once to the page of the Bad Hersfeld network.
FLEET_SIZE = 1000


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def server(tmp_path_factory):
    running = Workers(
        [TRACK_NET, GEO_NET], "--state-db", str(tmp_path_factory.mktemp("state") / "v.sqlite3"), workers=1
    )
    yield running
    running.stop()


@pytest.fixture(scope="module")
def client(server) -> httpx.Client:
    with httpx.Client(base_url=server.url, timeout=30.0) as http:
        yield http


def _open_map(browser, server, network: str) -> Recorded:
    recorded = Recorded(browser)
    recorded.page.goto(f"{server.url}/map?network={network}")
    recorded.page.wait_for_function("() => document.body.dataset.ready === 'true'", timeout=WAIT_MS)
    return recorded


def _assert_curves_as_served(page: Page, client: httpx.Client, network: str) -> int:
    """The curve layers drawn are the features /v1/curves answers for the page's view; how many."""
    drawn = page.evaluate("cswsMap.curves.getLayers().length")
    bbox = page.evaluate("document.body.dataset.curvesBbox")
    ids = page.evaluate("cswsMap.curves.getLayers().map(layer => layer.feature.id).sort()")
    served = client.get("/v1/curves", params={"network": network, "bbox": bbox}).json()["features"]
    assert drawn == len(served) == len(ids)
    assert ids == sorted(feature["id"] for feature in served)
    return drawn


def _colour_of(page: Page, answer: dict) -> str:
    """The colour the page's legend gives the state and level of an answer."""
    kind = f"active-{answer['level']}" if answer["state"] == "active" else answer["state"]
    return page.evaluate(f"cswsMap.styles[{kind!r}].fillColor")


def test_the_map_draws_the_curves_of_its_view_as_the_service_gives_them(browser, server, client) -> None:
    recorded = _open_map(browser, server, "t7_left")
    page = recorded.page
    assert _assert_curves_as_served(page, client, "t7_left") == 1  # the track's one (multi) curve
    # Zoomed into the approach, far from the curve: the view holds none, and the page draws none.
    page.evaluate("cswsMap.map.setView([0, 300], 3)")
    page.wait_for_function("() => document.body.dataset.curvesDrawn === '0'", timeout=WAIT_MS)
    assert _assert_curves_as_served(page, client, "t7_left") == 0
    recorded.assert_offline()


def test_vehicle_markers_appear_and_change_colour_when_a_warning_comes_on(browser, server, client) -> None:
    recorded = _open_map(browser, server, "t7_left")
    page = recorded.page
    fix = {"vehicle_id": "truck-18", "category": "N", "speed_kmh": 80.0, "heading_deg": 90.0, "network": "t7_left"}
    far = client.post("/v1/warning", json={**fix, "position": {"x": 300.0, "y": 0.4}, "timestamp_s": 1.0}).json()
    page.wait_for_function("() => cswsMap.vehicles.has('truck-18')", timeout=WAIT_MS)
    page.wait_for_function(
        "c => cswsMap.vehicles.get('truck-18').options.fillColor === c", arg=_colour_of(page, far), timeout=WAIT_MS
    )
    near = client.post("/v1/warning", json={**fix, "position": {"x": 985.0, "y": 0.4}, "timestamp_s": 2.0}).json()
    assert (far["level"], near["level"]) == (0, 2)
    assert _colour_of(page, near) != _colour_of(page, far)
    page.wait_for_function(
        "c => cswsMap.vehicles.get('truck-18').options.fillColor === c", arg=_colour_of(page, near), timeout=WAIT_MS
    )
    # Where the page puts it is where the service's fleet view does (x, y as Leaflet's lng, lat).
    placed = page.evaluate("(({lat, lng}) => [lng, lat])(cswsMap.vehicles.get('truck-18').getLatLng())")
    [served] = [
        f for f in client.get("/v1/fleet", params={"network": "t7_left"}).json()["features"] if f["id"] == "truck-18"
    ]
    assert placed == pytest.approx(served["geometry"]["coordinates"])
    recorded.assert_offline()


def test_a_fleet_of_a_thousand_on_a_real_network_is_drawn_from_little_data(browser, server, client, tmp_path) -> None:
    roads = client.get("/v1/roads", params={"network": "badhersfeld"}).json()["features"]
    lanes = [f"{road['id']}_0" for road in roads][:FLEET_SIZE]
    queries = [
        {
            "vehicle_id": f"truck-{i}",
            "category": "N",
            "speed_kmh": 30.0 + i % 70,
            "lane_id": lane,
            "lane_pos_m": 0.0,
            "network": "badhersfeld",
        }
        for i, lane in enumerate(lanes)
    ]
    answers = client.post("/v1/warnings", json={"queries": queries}).json()["answers"]
    recorded = _open_map(browser, server, "badhersfeld")
    page = recorded.page
    assert sum(recorded.body_sizes) <= INITIAL_DATA_LIMIT_BYTES
    assert _assert_curves_as_served(page, client, "badhersfeld") > 0
    page.wait_for_function(f"() => cswsMap.vehicles.size >= {FLEET_SIZE}", timeout=WAIT_MS)
    shown = page.evaluate("Object.fromEntries([...cswsMap.vehicles].map(([id, m]) => [id, m.options.fillColor]))")
    expected = {answer["vehicle_id"]: _colour_of(page, answer) for answer in answers}
    assert shown == expected
    page.screenshot(path=os.environ.get("CSWS_MAP_SCREENSHOT", str(tmp_path / "map.png")))
    recorded.assert_offline()


@pytest.mark.parametrize("path, rendered", [("/docs", ".swagger-ui .opblock"), ("/redoc", "[data-section-id]")])
def test_the_api_docs_render_with_nothing_from_elsewhere(browser, server, path, rendered) -> None:
    recorded = Recorded(browser)
    recorded.page.goto(server.url + path)
    recorded.page.wait_for_selector(rendered, timeout=WAIT_MS)
    assert recorded.page.locator(rendered).count() >= 5  # one per operation (or section)
    recorded.assert_offline()
