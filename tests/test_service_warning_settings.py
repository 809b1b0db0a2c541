"""The curve warning's settings per fleet: a settings file pins a fleet's update period, whether it is learnt and
the release rule; the fleet's vehicles are warned by them, every other fleet by the service's; a bad file stops
start-up naming it."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from fastapi.testclient import TestClient
from servers import free_port

from csws.networks import networks_dir
from csws.standard import kmh_to_mps, warning_speed
from csws.warning.settings import WarningSettings
from service.app import create_app
from service.keys import add_key
from service.settings import ServiceSettings
from service.warning_settings import WARNING_SETTINGS_FORMAT, FleetWarningSettings

TRACK_NET = str(networks_dir() / "single_r120_left.net.xml")
#: The track's curve: R 120 m, starting 100 m into lane ``curve_0``.
RADIUS_M, CURVE_LANE, CURVE_START_POS_M = 120.0, "curve_0", 100.0
#: A fleet whose terminals report every 5 s, pinned: its period is not learnt from their timestamps.
PINNED = {"update_period_s": 5.0, "learn_update_period": False}


def _settings_file(tmp_path, fleets: dict) -> str:
    path = tmp_path / "warning.json"
    path.write_text(json.dumps({"format": WARNING_SETTINGS_FORMAT, "fleets": fleets}))
    return str(path)


def _reach_m(speed_kmh: float, latency_s: float) -> float:
    """Formula (1) at level 1 for a category N vehicle at the track's curve, plus the distance driven during
    ``latency_s`` (6.1): S_w = 0.8 v + (v^2 - v_w^2) / g, m."""
    v, v_w = kmh_to_mps(speed_kmh), kmh_to_mps(warning_speed(RADIUS_M, "N", 1))
    return 0.8 * v + (v * v - v_w * v_w) / 9.8 + v * latency_s


def test_a_fleets_pinned_update_period_warns_its_vehicles_earlier_and_no_other_fleets(tmp_path):
    """Four fixes a second apart, then one 70 m before the curve at 72 km/h: the pinned fleet's vehicle is warned
    there (its 5 s period and the 0.1 s delay in the reach), the other fleet's, whose 1 s period is learnt from the
    same timestamps, is not; without timestamps the other fleet's configured 0.1 s holds."""
    keys = tmp_path / "keys.json"
    acme, globex = add_key(keys, "acme", "query"), add_key(keys, "globex", "query")
    settings = ServiceSettings(
        nets=[TRACK_NET],
        state_db=str(tmp_path / "v.sqlite3"),
        api_keys_file=keys,
        warning_settings_file=_settings_file(tmp_path, {"acme": PINNED}),
    )
    speed_kmh, before_m = 72.0, 70.0
    assert _reach_m(speed_kmh, 1.0 + 0.1) < before_m <= _reach_m(speed_kmh, 5.0 + 0.1)
    assert speed_kmh < warning_speed(RADIUS_M, "N", 2)  # level 1 at most

    def levels(key: str, timestamps: bool) -> list[int]:
        answered = []
        for k, back_m in enumerate((170.0, 150.0, 130.0, 110.0, before_m)):
            query = {"vehicle_id": "truck", "category": "N", "speed_kmh": speed_kmh, "lane_id": CURVE_LANE}
            query["lane_pos_m"] = CURVE_START_POS_M - back_m if back_m <= CURVE_START_POS_M else None
            if query["lane_pos_m"] is None:
                query |= {"lane_id": "approach_0", "lane_pos_m": 900.0 - (back_m - CURVE_START_POS_M)}
            if timestamps:
                query["timestamp_s"] = 100.0 + k
            response = client.post("/v1/warning", json=query, headers={"Authorization": f"Bearer {key}"})
            assert response.status_code == 200, response.text
            answered.append(response.json()["level"])
        return answered

    with TestClient(create_app(settings)) as client:
        assert levels(acme, timestamps=True)[-1] == 1
        assert levels(globex, timestamps=True)[-1] == 0
    assert _reach_m(speed_kmh, 0.1 + 0.1) < 110.0 - 20.0  # the first four fixes warn no one
    with TestClient(create_app(settings.model_copy(update={"state_db": str(tmp_path / "w.sqlite3")}))) as client:
        assert levels(globex, timestamps=False) == [0, 0, 0, 0, 0]
        assert levels(acme, timestamps=False)[-1] == 1


def test_without_a_file_every_fleet_has_the_services_settings():
    service = WarningSettings(update_period_s=1.0, release_hold_s=2.0)
    assert FleetWarningSettings(service).of("acme") is service


def test_a_fleets_block_pins_what_it_names_over_the_services_settings(tmp_path):
    service = WarningSettings(update_period_s=1.0, release_hold_s=2.0)
    path = _settings_file(tmp_path, {"acme": {**PINNED, "release_margin_kmh": 2}, "globex": {}})
    fleets = FleetWarningSettings(service, path)
    assert fleets.of("acme") == WarningSettings(
        update_period_s=5.0, learn_update_period=False, release_hold_s=2.0, release_margin_kmh=2.0
    )
    assert fleets.of("globex") == service
    assert fleets.of("other") is service


@pytest.mark.parametrize(
    ("content", "named"),
    [
        ({"format": WARNING_SETTINGS_FORMAT, "fleets": {"acme": {"system_delay_s": 0.5}}}, "system_delay_s"),
        ({"format": WARNING_SETTINGS_FORMAT, "fleets": {"acme": {"update_period_s": -1}}}, "update_period_s"),
        ({"format": WARNING_SETTINGS_FORMAT, "fleets": {"acme": {"update_period_s": "5"}}}, "must be a number"),
        ({"format": WARNING_SETTINGS_FORMAT, "fleets": {"acme": {"learn_update_period": 0}}}, "true or false"),
        ({"format": WARNING_SETTINGS_FORMAT, "fleets": ["acme"]}, "fleets"),
        ({"format": WARNING_SETTINGS_FORMAT, "fleets": {"acme": {"release_hold_s": 10**400}}}, "release_hold_s is too"),
        ({"format": WARNING_SETTINGS_FORMAT, "fleets": {"": {"release_hold_s": 2}}}, "name"),
        ({"format": "csws-fcw-settings/1"}, "expected format"),
    ],
)
def test_a_bad_settings_file_is_refused_naming_the_file_and_what_is_wrong(tmp_path, content, named):
    path = tmp_path / "warning.json"
    path.write_text(json.dumps(content))
    with pytest.raises(ValueError, match=str(path)) as refused:
        FleetWarningSettings(WarningSettings(), path)
    assert named in str(refused.value)


def test_serve_with_a_bad_settings_file_stops_with_one_line(tmp_path):
    path = _settings_file(tmp_path, {"acme": {"release_hold_s": -2}})
    done = subprocess.run(
        [sys.executable, "-m", "csws", "serve", f"--net={TRACK_NET}", "--warning-settings", path]
        + ["--state-db", str(tmp_path / "v.sqlite3"), "--port", str(free_port())],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode != 0
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert any(path in line and "release_hold_s" in line for line in lines), done.stderr
    assert "Traceback" not in done.stderr
