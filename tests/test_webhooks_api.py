"""A fleet's admin configures its own webhooks over the API (``/v1/webhooks``), against a real service on loopback.

The truth is independent of the routes: the service's own warning answers say which events a drive
makes, the receiver checks each POST's HMAC with the secret the API gave, the address rules'
reasons come from :func:`service.push.addresses.address_refusal`, the command line (``csws webhooks
list``) reads the same file, and dead letters are written into the push state as its dispatcher
writes them.
"""

from __future__ import annotations

import ipaddress
import json
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime
from pathlib import Path

import pytest
from builders import write_geo_track
from markers import marks_its_tests
from push_receivers import Receiver, signature_holds, wait_until
from servers import Server
from test_push_service import _changes, _drive

from csws.cli import main as csws_main
from service.keys import Role, add_key
from service.push.addresses import address_refusal
from service.push.state import Pending, PushState, push_db_beside
from service.push.targets import RELOAD_INTERVAL_S, SECRET_PREFIX
from service.routes.webhooks import MAX_FLEET_WEBHOOKS

FLEET, RIVAL = "acme", "rival"
#: When the dead letters of the test were given up, unix s.
DEAD_S = 1_800_000_000.0
ROUTES = [
    ("GET", "/v1/webhooks"),
    ("POST", "/v1/webhooks"),
    ("DELETE", "/v1/webhooks"),
    ("GET", "/v1/webhooks/dead-letters"),
]


class Fleets:
    """A service with API keys (loopback webhooks allowed, as a test's receiver is on loopback), and its keys."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        keys = folder / "api-keys.json"
        self.admin = {"Authorization": f"Bearer {add_key(keys, FLEET, Role.ADMIN)}"}
        self.query_key = add_key(keys, FLEET, Role.QUERY)
        self.rival = {"Authorization": f"Bearer {add_key(keys, RIVAL, Role.ADMIN)}"}
        self.webhooks_file = folder / "webhooks.json"  # beside the key file: the service's default
        self.state_db = folder / "vehicles.sqlite3"
        self.server = Server(
            [write_geo_track(folder)], self.state_db, api_keys_file=str(keys), webhook_allow_private="1"
        )

    def call(self, method: str, path: str, headers: dict[str, str], **kwargs):
        """One request to the service."""
        return self.server.client.request(method, path, headers=headers, **kwargs)

    def urls(self, headers: dict[str, str]) -> list[str]:
        """The URLs ``GET /v1/webhooks`` lists for the key of ``headers``."""
        response = self.call("GET", "/v1/webhooks", headers)
        assert response.status_code == 200, response.text
        return response.json()["urls"]


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def fleets(tmp_path_factory) -> Iterator[Fleets]:
    running = Fleets(tmp_path_factory.mktemp("fleets"))
    yield running
    running.server.stop()


@pytest.fixture
def receiver() -> Iterator[Receiver]:
    running = Receiver()
    yield running
    running.stop()


def _cli_list(file: Path, capsys) -> list[tuple[str, ...]]:
    """What ``csws webhooks list`` shows: (fleet, URL) per line."""
    capsys.readouterr()
    assert csws_main(["webhooks", "list", "--file", str(file)]) == 0
    return [tuple(line.split("  ", 1)) for line in capsys.readouterr().out.splitlines()]


def test_a_fleet_admin_adds_a_webhook_and_the_next_warnings_reach_it_signed_with_the_secret_given(fleets, receiver):
    added = fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": receiver.url})
    assert added.status_code == 201, added.text
    secret = added.json()["secret"]
    assert added.headers["cache-control"] == "no-store"
    assert secret.startswith(SECRET_PREFIX) and added.json()["url"] == receiver.url
    assert fleets.urls(fleets.admin) == [receiver.url]
    time.sleep(RELOAD_INTERVAL_S + 1.0)  # every worker reads the file again within RELOAD_INTERVAL_S of a change
    answers = _drive(fleets.server, fleets.query_key, "api-truck")
    changes = _changes(answers)
    assert any(level == 2 for level, _ in changes)
    wait_until(lambda: len(receiver.accepted()) >= len(changes))
    posted = [json.loads(request["body"]) for request in receiver.accepted()]
    assert all(signature_holds(secret, request) for request in receiver.accepted())
    assert [(event["level"], event["state"]) for event in posted] == changes
    assert {(event["fleet"], event["vehicle_id"]) for event in posted} == {(FLEET, "api-truck")}
    again = fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": receiver.url})
    assert again.status_code == 409
    assert fleets.call("DELETE", "/v1/webhooks", fleets.admin, params={"url": receiver.url}).status_code == 204
    assert fleets.urls(fleets.admin) == []
    assert fleets.call("DELETE", "/v1/webhooks", fleets.admin, params={"url": receiver.url}).status_code == 404


def test_a_fleet_s_second_url_shares_its_secret_which_is_not_given_again(fleets):
    first, second = "http://127.0.0.1:9/first", "http://127.0.0.1:9/second"
    assert fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": first}).json()["secret"] is not None
    shared = fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": second})
    assert shared.status_code == 201 and shared.json() == {"url": second, "secret": None}
    assert fleets.urls(fleets.admin) == [first, second]
    assert "secret" not in fleets.call("GET", "/v1/webhooks", fleets.admin).text.replace('"urls"', "")
    for url in (first, second):
        assert fleets.call("DELETE", "/v1/webhooks", fleets.admin, params={"url": url}).status_code == 204


def test_a_fleet_has_at_most_max_fleet_webhooks_urls(fleets):
    urls = [f"http://127.0.0.1:9/{number}" for number in range(MAX_FLEET_WEBHOOKS + 1)]
    for url in urls[:-1]:
        assert fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": url}).status_code == 201
    refused = fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": urls[-1]})
    assert refused.status_code == 409 and str(MAX_FLEET_WEBHOOKS) in refused.json()["detail"]
    assert fleets.urls(fleets.admin) == urls[:-1]
    assert fleets.call("POST", "/v1/webhooks", fleets.rival, json={"url": urls[-1]}).status_code == 201
    for url in urls[:-1]:
        assert fleets.call("DELETE", "/v1/webhooks", fleets.admin, params={"url": url}).status_code == 204
    assert fleets.call("DELETE", "/v1/webhooks", fleets.rival, params={"url": urls[-1]}).status_code == 204


def test_urls_added_at_once_are_all_kept(fleets):
    urls = [f"http://127.0.0.1:9/at-once-{number}" for number in range(MAX_FLEET_WEBHOOKS)]
    with ThreadPoolExecutor(len(urls)) as pool:
        answers = list(pool.map(lambda url: fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": url}), urls))
    assert [answer.status_code for answer in answers] == [201] * len(urls)
    assert sum(answer.json()["secret"] is not None for answer in answers) == 1  # one secret, made with the first
    assert sorted(fleets.urls(fleets.admin)) == sorted(urls)
    with ThreadPoolExecutor(len(urls)) as pool:
        removed = list(
            pool.map(lambda url: fleets.call("DELETE", "/v1/webhooks", fleets.admin, params={"url": url}), urls)
        )
    assert [answer.status_code for answer in removed] == [204] * len(urls) and fleets.urls(fleets.admin) == []


def test_a_query_key_is_refused_and_no_key_is_a_401(fleets):
    query = {"Authorization": f"Bearer {fleets.query_key}"}
    for method, path in ROUTES:
        body = {"json": {"url": "http://127.0.0.1:9/"}} if method == "POST" else {}
        params = {"params": {"url": "http://127.0.0.1:9/"}} if method == "DELETE" else {}
        assert fleets.call(method, path, query, **body, **params).status_code == 403, (method, path)
        assert fleets.call(method, path, {}, **body, **params).status_code == 401, (method, path)
    assert fleets.urls(fleets.admin) == []


def test_another_fleet_s_admin_neither_sees_nor_removes_a_fleet_s_webhook(fleets):
    url = "http://127.0.0.1:9/acme-only"
    assert fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": url}).status_code == 201
    listed = fleets.call("GET", "/v1/webhooks", fleets.rival).json()
    assert listed == {"fleet": RIVAL, "urls": []}
    assert fleets.call("DELETE", "/v1/webhooks", fleets.rival, params={"url": url}).status_code == 404
    assert fleets.urls(fleets.admin) == [url]
    assert fleets.call("DELETE", "/v1/webhooks", fleets.admin, params={"url": url}).status_code == 204


@pytest.mark.parametrize(
    ("url", "address"),
    [
        ("http://169.254.169.254/latest/meta-data/", "169.254.169.254"),
        ("http://100.100.100.200/latest/meta-data/", "100.100.100.200"),
        ("http://[fd00:ec2::254]/", "fd00:ec2::254"),
        ("http://169.254.10.1/hook", "169.254.10.1"),
        ("https://[fe80::1]:8443/hook", "fe80::1"),
        ("http://[::ffff:169.254.169.254]/", "169.254.169.254"),
    ],
)
def test_link_local_and_metadata_urls_are_422_naming_the_rule(fleets, url, address):
    reason = address_refusal(ipaddress.ip_address(address), allow_private=True)
    assert reason is not None  # refused even where loopback and private addresses are allowed
    refused = fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": url})
    assert refused.status_code == 422 and reason in refused.json()["detail"], refused.text
    assert url not in fleets.urls(fleets.admin)


def test_a_url_that_is_no_http_url_is_a_422_and_a_huge_one_a_validation_error(fleets):
    for url in ("ftp://127.0.0.1/hook", "http://", "no url at all"):
        refused = fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": url})
        assert refused.status_code == 422 and isinstance(refused.json()["detail"], str), refused.text
    huge = fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": "http://127.0.0.1/" + "a" * 2048})
    assert huge.status_code == 422 and isinstance(huge.json()["detail"], list)
    as_json = {**fleets.admin, "Content-Type": "application/json"}
    not_utf8 = fleets.call("POST", "/v1/webhooks", as_json, content=b"\xa0\x05\xb3")
    assert not_utf8.status_code == 422 and isinstance(not_utf8.json()["detail"], list)


def test_the_command_line_and_the_api_see_the_same_list(fleets, capsys):
    by_cli, by_api = "http://127.0.0.1:9/by-cli", "http://127.0.0.1:9/by-api"
    file = fleets.webhooks_file
    assert csws_main(["webhooks", "add", "--fleet", FLEET, by_cli, "--allow-private", "--file", str(file)]) == 0
    assert fleets.urls(fleets.admin) == [by_cli]
    assert fleets.call("POST", "/v1/webhooks", fleets.admin, json={"url": by_api}).json()["secret"] is None
    assert _cli_list(file, capsys) == [(FLEET, by_cli), (FLEET, by_api)]
    assert fleets.call("DELETE", "/v1/webhooks", fleets.admin, params={"url": by_cli}).status_code == 204
    assert _cli_list(file, capsys) == [(FLEET, by_api)]
    assert csws_main(["webhooks", "remove", "--fleet", FLEET, by_api, "--file", str(file)]) == 0
    assert fleets.urls(fleets.admin) == [] and _cli_list(file, capsys) == []


def test_each_fleet_admin_reads_its_own_dead_letters(fleets):
    answers = _drive(fleets.server, fleets.query_key, "dead-truck")
    assert answers
    history = fleets.call("GET", "/v1/vehicles/dead-truck/events", fleets.admin, params={"since": 0})
    assert history.status_code == 200, history.text
    event = history.json()["events"][0]
    state = PushState(push_db_beside(str(fleets.state_db)))
    try:
        for fleet, url in ((FLEET, "http://127.0.0.1:9/gone"), (RIVAL, "http://127.0.0.1:9/rival")):
            body = json.dumps({**event, "fleet": fleet}).encode()
            pending = Pending(0, f"webhook {fleet} {url}", f"{fleet}/dead-truck", body, 8, 0.0, 0.0, "")
            state.dead(pending, 8, "HTTP 503", DEAD_S)
    finally:
        state.close()
    shown = fleets.call("GET", "/v1/webhooks/dead-letters", fleets.admin)
    assert shown.status_code == 200, shown.text
    letters = shown.json()["dead_letters"]
    assert [(row["url"], row["vehicle_id"], row["tries"], row["error"]) for row in letters] == [
        ("http://127.0.0.1:9/gone", "dead-truck", 8, "HTTP 503")
    ]
    assert datetime.fromisoformat(letters[0]["dead"]) == datetime.fromtimestamp(DEAD_S, UTC) and letters[0][
        "event"
    ] == {**event, "fleet": FLEET}
    assert [
        row["url"] for row in fleets.call("GET", "/v1/webhooks/dead-letters", fleets.rival).json()["dead_letters"]
    ] == ["http://127.0.0.1:9/rival"]


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def open_service(tmp_path_factory) -> Iterator[Server]:
    folder = tmp_path_factory.mktemp("open")
    running = Server([write_geo_track(folder)], folder / "vehicles.sqlite3")
    yield running
    running.stop()


def test_a_service_without_keys_has_no_fleet_to_give_webhooks_to(open_service):
    for method, path in ROUTES:
        body = {"json": {"url": "https://dispatch.example.com/csws"}} if method == "POST" else {}
        params = {"params": {"url": "https://dispatch.example.com/csws"}} if method == "DELETE" else {}
        refused = open_service.client.request(method, path, **body, **params)
        assert refused.status_code == 403 and "no API keys" in refused.json()["detail"], (method, path)
