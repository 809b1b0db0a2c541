"""Fuzz the HTTP API from its own OpenAPI schema with schemathesis, against a real uvicorn on loopback.

The schema is the one the service publishes (``/openapi.json``: the same app's, built
in-process); every request goes over loopback to a service that serves the Table 7
track geo-referenced, so that lon/lat fixes reach the projection. The run is bounded
and deterministic: a fixed seed, at most :data:`MAX_EXAMPLES` generated cases per
operation plus the schema's examples and schemathesis' coverage cases, and no
stateful phase.

What must hold for every case: no 5xx; every response body, content type and header
matches what the schema documents for it; and every status code is documented.
Bad input answered with a documented 4xx (422) is a pass. The answers the fuzzing once
found undocumented (a body that is not UTF-8, an unknown vehicle) are also checked
directly, so that they stay documented.

The schema is loaded at import rather than from a pytest fixture because schemathesis'
lazy fixture loader does not run under pytest 9.
"""

from __future__ import annotations

import pytest
import schemathesis
from builders import write_geo_track
from hypothesis import settings
from markers import marks_its_tests
from schemathesis import checks
from servers import Server

from csws.networks import networks_dir
from service.app import create_app
from service.settings import ServiceSettings

SEED = 20180091
MAX_EXAMPLES = 100

CONFIG = schemathesis.Config.from_dict(
    {"seed": SEED, "generation": {"max-examples": MAX_EXAMPLES}, "phases": {"stateful": {"enabled": False}}}
)
SCHEMA = schemathesis.openapi.from_dict(
    create_app(ServiceSettings(nets=[networks_dir() / "t7_left.net.xml"], state_db=":memory:")).openapi(),
    config=CONFIG,
)
#: What every answer must satisfy: no server error, and a body, content type and headers as documented.
RESPONSE_CHECKS = [
    checks.not_a_server_error,
    checks.response_schema_conformance,
    checks.content_type_conformance,
    checks.response_headers_conformance,
]
#: Answers whose status codes the fuzzing found undocumented once: (method, path template, URL, body) each.
EDGE_STATUS_CASES = {
    "put-vehicle-body-not-utf-8": ("PUT", "/v1/vehicles/{vehicle_id}", "/v1/vehicles/v1", b"\xa0\x05\xb3\x07"),
    "get-unknown-vehicle": ("GET", "/v1/vehicles/{vehicle_id}", "/v1/vehicles/never-seen", None),
}


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def server(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzzed")
    running = Server([write_geo_track(folder)], folder / "vehicles.sqlite3")
    yield running
    running.stop()


@SCHEMA.parametrize()
@settings(deadline=None, database=None)
def test_no_server_error_and_every_answer_matches_the_schema(case, server) -> None:
    case.call_and_validate(base_url=server.url, checks=RESPONSE_CHECKS)


@SCHEMA.parametrize()
@settings(deadline=None, database=None)
def test_every_status_code_is_documented(case, server) -> None:
    case.call_and_validate(base_url=server.url, checks=[checks.status_code_conformance])


@pytest.mark.parametrize("method, path, url, body", EDGE_STATUS_CASES.values(), ids=EDGE_STATUS_CASES.keys())
def test_edge_answers_have_documented_status_codes(server, method, path, url, body) -> None:
    documented = server.client.get("/openapi.json").json()["paths"][path][method.lower()]["responses"]
    response = server.client.request(method, url, content=body, headers={"content-type": "application/json"})
    assert str(response.status_code) in documented, response.text
