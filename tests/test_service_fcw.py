"""The service's forward_target: the answer's fcw is the library's, from the seed's formulas; the
curve warning's answers are unchanged without one; bad targets are a 422 that names the field."""

from __future__ import annotations

import math

import pytest
from fastapi.testclient import TestClient

from csws.fcw.physics import evaluate_fcw
from csws.networks import networks_dir
from service.app import create_app
from service.schemas import FcwAnswer, ForwardTarget
from service.settings import ServiceSettings

TRACK_NET = str(networks_dir() / "single_r120_left.net.xml")


@pytest.fixture
def client(tmp_path):
    settings = ServiceSettings(nets=[TRACK_NET], state_db=str(tmp_path / "vehicles.sqlite3"))
    with TestClient(create_app(settings)) as client:
        yield client


def _query(vehicle_id: str, speed_kmh: float = 72.0, **extra) -> dict:
    return {
        "vehicle_id": vehicle_id,
        "category": "N",
        "speed_kmh": speed_kmh,
        "lane_id": "approach_0",
        "lane_pos_m": 100.0,
        "timestamp_s": 1.0,
        **extra,
    }


def test_a_forward_target_gets_the_fcw_of_the_seeds_formulas(client):
    target = {"range_m": 40.0, "range_rate_mps": -15.0, "target_accel_mps2": -1.0}
    answer = client.post("/v1/warning", json=_query("truck-1", forward_target=target)).json()
    fcw = answer["fcw"]
    assert fcw["ttc_s"] == pytest.approx(40.0 / 15.0)  # formula (2)
    assert fcw["ettc_s"] == pytest.approx((15.0 - math.sqrt(15.0**2 + 2.0 * 1.0 * 40.0)) / -1.0)  # formula (3)
    # formula (4) at the end of T_resp 1.2 s, the lead braking at 1 m/s^2 through it: closing 15 + 1.2 m/s,
    # clearance 40 - 15 * 1.2 - 1.2**2 / 2 m
    assert fcw["a_req_mps2"] == pytest.approx(1.0 + (15.0 + 1.2) ** 2 / (2.0 * (40.0 - 15.0 * 1.2 - 1.2**2 / 2.0)))
    library = evaluate_fcw([0.0], [40.0], [-15.0], [-1.0], [False])
    assert (fcw["state"], fcw["level"]) == ("active", int(library.level[0])) == ("active", 2)
    assert "level" in answer and answer["vehicle_id"] == "truck-1"


def test_the_batch_answers_fcw_only_where_asked_and_the_state_follows_the_speed(client):
    queries = [
        _query("a"),
        _query("b", speed_kmh=20.0, forward_target={"range_m": 10.0, "range_rate_mps": -5.0}),
        _query("c", forward_target={"range_m": 10.0, "range_rate_mps": -5.0, "measured": False}),
        _query("d", forward_target={"range_m": 80.0, "range_rate_mps": 2.0}),
    ]
    answers = client.post("/v1/warnings", json={"queries": queries}).json()["answers"]
    assert "fcw" not in answers[0]
    assert [(a["fcw"]["state"], a["fcw"]["level"]) for a in answers[1:]] == [
        ("standby", 0),
        ("fault", 0),
        ("active", 0),
    ]
    assert answers[3]["fcw"]["ttc_s"] is None  # opening: no collision


def test_without_a_forward_target_the_answer_is_as_before(client):
    plain = client.post("/v1/warning", json=_query("e")).content
    assert b"fcw" not in plain


@pytest.mark.parametrize(
    ("target", "field"),
    [
        ({"range_rate_mps": -5.0}, "range_m"),
        ({"range_m": -1.0, "range_rate_mps": -5.0}, "range_m"),
        ({"range_m": 10.0, "range_rate_mps": "fast"}, "range_rate_mps"),
        ({"range_m": 10.0, "range_rate_mps": -5.0, "measured": 1}, "measured"),
    ],
)
def test_a_bad_forward_target_is_a_422_naming_the_field(client, target, field):
    response = client.post("/v1/warnings", json={"queries": [_query("f", forward_target=target)]})
    assert response.status_code == 422
    locs = [error["loc"] for error in response.json()["detail"]]
    assert ["body", "queries", 0, "forward_target", field] in locs


def test_the_schema_examples_of_a_target_and_its_answer_agree(client):
    """The OpenAPI example of an fcw answer is what the service answers to the example target."""
    target = ForwardTarget.model_config["json_schema_extra"]["examples"][0]
    answer = client.post("/v1/warning", json=_query("truck-ex", speed_kmh=60.0, forward_target=target)).json()["fcw"]
    example = FcwAnswer.model_config["json_schema_extra"]["examples"][0]
    assert {name: answer[name] for name in ("state", "level")} == {name: example[name] for name in ("state", "level")}
    for name in ("ttc_s", "ettc_s", "a_req_mps2"):
        assert answer[name] == pytest.approx(example[name], abs=0.005)
