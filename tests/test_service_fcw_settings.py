"""The service's FCW settings per fleet: a settings file sets the thresholds and V_max, a fleet's block applies
over the default to that fleet only, and a bad file stops start-up naming it."""

from __future__ import annotations

import json

import pytest
from fastapi.testclient import TestClient
from fcw_queries import TRACK_NET, fcw_query, stopped_car, stopped_car_level

from csws.fcw.settings import FcwSettings
from csws.standard import Category
from service.app import create_app
from service.fcw_settings import FleetFcwSettings
from service.settings import ServiceSettings


def test_a_fleet_settings_file_sets_the_thresholds_and_v_max(tmp_path):
    path = tmp_path / "fcw.json"
    settings_file = {
        "format": "csws-fcw-settings/1",
        "default": {"collision_a_req_mps2": 4.0, "max_speed_by_category_mps": {"N": 35.0}},
    }
    path.write_text(json.dumps(settings_file))
    settings = ServiceSettings(nets=[TRACK_NET], state_db=str(tmp_path / "v.sqlite3"), fcw_settings_file=path)
    own = FcwSettings.for_category("N", collision_a_req_mps2=4.0, max_speed_mps=35.0)
    # a_req of 4.5 m/s^2: below the library's 0.5 g, above the fleet's 4.0
    speed_mps = 20.0
    x_m = 1.2 * speed_mps + speed_mps**2 / (2.0 * 4.5)
    with TestClient(create_app(settings)) as client:
        fcw = client.post("/v1/warning", json=fcw_query("fleet", objects=[stopped_car(x_m, speed_mps)])).json()["fcw"]
        fast = client.post("/v1/warning", json=fcw_query("fast", speed_kmh=120.0, objects=[])).json()["fcw"]
    assert fcw["a_req_mps2"] == pytest.approx(4.5)
    assert fcw["level"] == stopped_car_level(x_m, speed_mps, own) == 2 != stopped_car_level(x_m, speed_mps)
    assert fast["state"] == "active"  # 33.3 m/s: within the fleet's V_max for N


@pytest.mark.parametrize(
    "content",
    [
        {"format": "csws-fcw-settings/1", "default": {"collision_a_req_mps2": 9.0}},  # above 0.68 g (4.5.3)
        {"format": "csws-fcw-settings/1", "fleets": {"acme": {"reaction_s": 1.0}}},
        {"format": "other"},
    ],
)
def test_a_bad_fleet_settings_file_stops_start_up_naming_it(tmp_path, content):
    path = tmp_path / "fcw.json"
    path.write_text(json.dumps(content))
    with pytest.raises(ValueError, match=str(path)):
        FleetFcwSettings(path)


def test_a_fleets_block_applies_over_the_default_to_that_fleet_only(tmp_path):
    path = tmp_path / "fcw.json"
    default = {"reaction_time_s": 1.4, "max_speed_by_category_mps": {"N": 30.0}}
    acme = {"collision_a_req_mps2": 4.0, "max_speed_by_category_mps": {"M1": 60.0}}
    path.write_text(json.dumps({"format": "csws-fcw-settings/1", "default": default, "fleets": {"acme": acme}}))
    fleets = FleetFcwSettings(path)
    assert fleets.of("acme", Category.N) == FcwSettings.for_category(
        "N", reaction_time_s=1.4, collision_a_req_mps2=4.0, max_speed_mps=30.0
    )
    assert fleets.of("acme", Category.M1) == FcwSettings.for_category(
        "M1", reaction_time_s=1.4, collision_a_req_mps2=4.0, max_speed_mps=60.0
    )
    assert fleets.of("other", Category.M1) == FcwSettings.for_category("M1", reaction_time_s=1.4)
    assert FleetFcwSettings().of("", Category.M3) == FcwSettings.for_category("M3")
