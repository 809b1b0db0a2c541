"""Fuzz the HTTP API from its own OpenAPI schema with schemathesis, against a real uvicorn on loopback with API keys.

The schema is the one the service publishes (``/openapi.json``: the same app's, built
in-process); every request goes over loopback to a service with an API key file that
serves the Table 7 track geo-referenced, so that lon/lat fixes reach the projection, and
carries a fleet's admin key, so that every route does its work rather than answer 401.
Two runs, bounded and deterministic (a fixed seed):

* every operation alone: at most :data:`MAX_EXAMPLES` generated cases per operation plus
  the schema's examples and schemathesis' coverage cases;
* sequences (schemathesis' stateful phase): :data:`STATEFUL_SEQUENCES` sequences of at
  most :data:`STATEFUL_STEPS` calls, each call chained to an earlier answer along the
  schema's links (a vehicle set, then read; a page of the fleet, then the next one by its
  ``next_cursor``).

What must hold for every case: no 5xx; every response body, content type and header
matches what the schema documents for it; and every status code is documented.
Bad input answered with a documented 4xx (422) is a pass. The answers the fuzzing once
found undocumented (a body that is not UTF-8, an unknown vehicle) are also checked
directly, so that they stay documented. ``python -m benchmarks.fuzz`` is the longer run.

The schema is loaded at import rather than from a pytest fixture because schemathesis'
lazy fixture loader does not run under pytest 9.
"""

from __future__ import annotations

import os

import pytest
import schemathesis
from builders import write_geo_track
from hypothesis import HealthCheck, settings
from markers import marks_its_tests
from schemathesis import checks
from servers import Server

from csws.networks import networks_dir
from service.app import create_app
from service.keys import Role, add_key
from service.settings import ServiceSettings

SEED = 20180091
#: The run's bounds, kept within the CI budget; ``python -m benchmarks.fuzz`` raises them (``CSWS_FUZZ_*``).
MAX_EXAMPLES = int(os.environ.get("CSWS_FUZZ_MAX_EXAMPLES", "40"))
STATEFUL_SEQUENCES = int(os.environ.get("CSWS_FUZZ_SEQUENCES", "25"))
STATEFUL_STEPS = int(os.environ.get("CSWS_FUZZ_STEPS", "6"))
#: How long a case may wait for its answer, s: the coverage phase sends the largest batch the schema allows.
TIMEOUT_S = 60.0

CONFIG = schemathesis.Config.from_dict(
    {"seed": SEED, "generation": {"max-examples": MAX_EXAMPLES}, "phases": {"stateful": {"enabled": True}}}
)
SCHEMA = schemathesis.openapi.from_dict(
    create_app(ServiceSettings(nets=[networks_dir() / "t7_left.net.xml"], state_db=":memory:")).openapi(),
    config=CONFIG,
)
#: What every answer must satisfy: no server error; a status code, body, content type and headers as documented.
RESPONSE_CHECKS = [
    checks.not_a_server_error,
    checks.status_code_conformance,
    checks.response_schema_conformance,
    checks.content_type_conformance,
    checks.response_headers_conformance,
]
#: Answers whose status codes the fuzzing found undocumented once: (method, path template, URL, body) each.
EDGE_STATUS_CASES = {
    "put-vehicle-body-not-utf-8": ("PUT", "/v1/vehicles/{vehicle_id}", "/v1/vehicles/v1", b"\xa0\x05\xb3\x07"),
    "get-unknown-vehicle": ("GET", "/v1/vehicles/{vehicle_id}", "/v1/vehicles/never-seen", None),
}


class KeyedServer(Server):
    """The service with an API key file holding one admin key of the fleet ``fuzz``; ``headers`` carry it."""

    def __init__(self, folder) -> None:
        keys = folder / "api-keys.json"
        self.headers = {"Authorization": f"Bearer {add_key(keys, 'fuzz', Role.ADMIN)}"}
        super().__init__([write_geo_track(folder)], folder / "vehicles.sqlite3", api_keys_file=str(keys))


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def server(tmp_path_factory):
    running = KeyedServer(tmp_path_factory.mktemp("fuzzed"))
    yield running
    running.stop()


#: Every test here runs in the suite's one-process run (the README's ``pytest -m serial``): under pytest-xdist,
#: schemathesis runs one operation of :func:`test_no_server_error_and_every_answer_is_documented` and passes.
pytestmark = pytest.mark.serial


@SCHEMA.parametrize()
@settings(deadline=None, database=None)
def test_no_server_error_and_every_answer_is_documented(case, server) -> None:
    assert "PYTEST_XDIST_WORKER" not in os.environ, "run without pytest-xdist's -n: only one operation is fuzzed there"
    case.call_and_validate(base_url=server.url, headers=server.headers, checks=RESPONSE_CHECKS, timeout=TIMEOUT_S)


class Sequences(SCHEMA.as_state_machine()):  # type: ignore[misc]
    """Calls chained along the schema's links, each with the fleet's key, each answer checked."""

    server: KeyedServer

    def get_call_kwargs(self, case: schemathesis.Case) -> dict:
        return {"base_url": self.server.url, "headers": self.server.headers, "timeout": TIMEOUT_S}

    def validate_response(self, response, case, additional_checks=None, **kwargs) -> None:
        for check in RESPONSE_CHECKS:
            case.validate_response(response, checks=[check], transport_kwargs=kwargs)


def test_sequences_along_the_links_answer_as_documented(server) -> None:
    assert Sequences.bundles, "the schema has no links to follow"
    Sequences.server = server
    Sequences.run(
        settings=settings(
            max_examples=STATEFUL_SEQUENCES,
            stateful_step_count=STATEFUL_STEPS,
            deadline=None,
            database=None,
            derandomize=True,
            suppress_health_check=list(HealthCheck),
        )
    )


@pytest.mark.parametrize("method, path, url, body", EDGE_STATUS_CASES.values(), ids=EDGE_STATUS_CASES.keys())
def test_edge_answers_have_documented_status_codes(server, method, path, url, body) -> None:
    schema = server.client.get("/openapi.json", headers=server.headers).json()
    documented = schema["paths"][path][method.lower()]["responses"]
    headers = {"content-type": "application/json", **server.headers}
    response = server.client.request(method, url, content=body, headers=headers)
    assert str(response.status_code) in documented, response.text
