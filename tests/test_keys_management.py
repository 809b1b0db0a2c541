"""Managing the fleets' keys: ``csws keys add | list | revoke | rotate``, and a running service taking
every change of the key file without a restart, in each of its workers.

The file is checked through the library (:mod:`service.keys`), the commands as a user runs them, and
the service as ``csws serve --workers 2`` on loopback (:class:`servers.Workers`).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from builders import TRACK_NET
from fastapi.testclient import TestClient
from servers import Workers

from service.app import create_app
from service.keys import (
    FINGERPRINT_DIGITS,
    KeyRing,
    Role,
    add_key,
    list_keys,
    revoke_key,
)
from service.security import MISSING_KEY, UNKNOWN_KEY
from service.settings import ServiceSettings

#: How long a running service may take to see a changed key file (its check interval is 1 s), s.
PICKUP_S = 10.0


def _fingerprint(key: str) -> str:
    """A key's fingerprint as the test works it out: the first hex digits of its SHA-256."""
    return hashlib.sha256(key.encode()).hexdigest()[:FINGERPRINT_DIGITS]


def _csws(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "csws", *args], capture_output=True, text=True, timeout=120)


def _auth(key: str) -> dict:
    return {"Authorization": f"Bearer {key}"}


def _query(vehicle_id: str) -> dict:
    return {"vehicle_id": vehicle_id, "category": "N", "speed_kmh": 80.0, "lane_id": "curve_0", "lane_pos_m": 85.0}


def test_list_shows_fleet_label_role_date_and_fingerprint_never_a_key(tmp_path) -> None:
    path = tmp_path / "keys.json"
    made = [
        _csws("keys", "add", "acme", "--role", "admin", "--label", "dispatch desk", "--file", str(path)),
        _csws("keys", "add", "other", "--file", str(path)),
    ]
    assert all(run.returncode == 0 for run in made), [run.stderr for run in made]
    keys = [run.stdout.strip() for run in made]
    listed = _csws("keys", "list", "--file", str(path))
    assert listed.returncode == 0, listed.stderr
    assert all(key not in listed.stdout and key[len("csws_") :][:8] not in listed.stdout for key in keys)
    header, *rows = listed.stdout.splitlines()
    assert header.split() == ["FINGERPRINT", "FLEET", "ROLE", "LABEL", "ADDED"]
    assert rows[0].startswith(f"{_fingerprint(keys[0])}  acme ") and "admin" in rows[0] and "dispatch desk" in rows[0]
    assert rows[1].startswith(f"{_fingerprint(keys[1])}  other") and " query " in rows[1]
    entries = list_keys(path)
    assert [(e.fleet, e.role, e.label) for e in entries] == [
        ("acme", Role.ADMIN, "dispatch desk"),
        ("other", Role.QUERY, ""),
    ]
    assert all(e.added.endswith("Z") for e in entries)


def test_labels_name_one_key_each(tmp_path) -> None:
    path = tmp_path / "keys.json"
    add_key(path, "acme", "query", label="unit-7")
    with pytest.raises(ValueError, match="labelled 'unit-7' is there already"):
        add_key(path, "other", "query", label="unit-7")
    with pytest.raises(ValueError, match="a label is 1-64 printable characters"):
        add_key(path, "acme", "query", label=" padded")
    assert len(list_keys(path)) == 1


def test_revoke_by_label_or_fingerprint_takes_only_that_key(tmp_path) -> None:
    path = tmp_path / "keys.json"
    first, second, third = (add_key(path, "acme", "query", label=f"unit-{n}") for n in range(3))
    revoke_key(path, "unit-1")
    revoke_key(path, _fingerprint(third)[:6].upper())
    ring = KeyRing(path)
    assert ring.principal(first) is not None and ring.principal(second) is None and ring.principal(third) is None
    for selector, message in (("unit-1", "no key has the label"), ("abc", "no key has the label")):
        with pytest.raises(ValueError, match=message):
            revoke_key(path, selector)


def test_a_fingerprint_that_matches_several_keys_is_refused(tmp_path) -> None:
    path = tmp_path / "keys.json"
    keys = [add_key(path, "acme", "query") for _ in range(2)]
    # Two keys whose hashes share their first six digits: the file edited so (one in 16 million otherwise).
    content = json.loads(path.read_text())
    first, second = (entry["sha256"] for entry in content["keys"])
    content["keys"][1]["sha256"] = first[:6] + ("0" if first[6] != "0" else "1") + second[7:]
    path.write_text(json.dumps(content))
    with pytest.raises(ValueError, match="matches 2 keys"):
        revoke_key(path, _fingerprint(keys[0])[:6])
    revoke_key(path, _fingerprint(keys[0])[:7])
    assert [entry.fingerprint for entry in list_keys(path)] == [content["keys"][1]["sha256"][:FINGERPRINT_DIGITS]]


def test_rotate_prints_a_new_key_of_the_same_fleet_role_and_label_and_revokes_the_old(tmp_path) -> None:
    path = tmp_path / "keys.json"
    old = add_key(path, "acme", "admin", label="backend")
    rotated = _csws("keys", "rotate", "backend", "--file", str(path))
    assert rotated.returncode == 0, rotated.stderr
    new = rotated.stdout.strip()
    assert new.startswith("csws_") and new != old and "shown only this once" in rotated.stderr
    ring = KeyRing(path)
    assert (
        ring.principal(old) is None and ring.principal(new).fleet == "acme" and ring.principal(new).role is Role.ADMIN
    )
    assert [(e.fingerprint, e.label) for e in list_keys(path)] == [(_fingerprint(new), "backend")]
    gone = _csws("keys", "revoke", _fingerprint(old), "--file", str(path))
    assert gone.returncode == 2 and gone.stderr.count("\n") == 1


def test_a_keyring_reads_its_file_again_when_it_changes(tmp_path) -> None:
    path = tmp_path / "keys.json"
    kept = add_key(path, "acme", "query", label="kept")
    ring = KeyRing(path, reload_interval_s=0.0)
    added = add_key(path, "other", "admin")
    assert ring.principal(added).fleet == "other"
    revoke_key(path, "kept")
    assert ring.principal(kept) is None
    path.write_text("{not json")  # a half-written edit by hand: the keys last read stay in force
    assert ring.principal(added).fleet == "other" and str(path) in (ring.reload_error or "")


def test_a_revoked_key_is_refused_by_a_running_app_without_restart(tmp_path) -> None:
    path = tmp_path / "keys.json"
    key = add_key(path, "acme", "query", label="unit")
    settings = ServiceSettings(nets=[TRACK_NET], api_keys_file=path, state_db=":memory:")
    with TestClient(create_app(settings)) as client:
        assert client.post("/v1/warning", json=_query("truck"), headers=_auth(key)).status_code == 200
        revoke_key(path, "unit")
        refused = _refused(client, key)
        assert refused.json()["detail"] == UNKNOWN_KEY
        missing = client.post("/v1/warning", json=_query("truck"))
        assert missing.status_code == 401 and missing.json()["detail"] == MISSING_KEY


def _refused(client, key: str) -> httpx.Response:
    """The answer to a query with ``key`` once it is a 401 (asked again until :data:`PICKUP_S` has passed)."""
    deadline = time.monotonic() + PICKUP_S
    while True:
        answer = client.post("/v1/warning", json=_query("truck"), headers=_auth(key))
        if answer.status_code == 401 or time.monotonic() > deadline:
            assert answer.status_code == 401, answer.text
            return answer
        time.sleep(0.1)


@pytest.mark.slow
def test_revoke_and_rotate_take_effect_in_every_worker_of_a_running_service(tmp_path: Path) -> None:
    path = tmp_path / "keys.json"
    revoked = add_key(path, "acme", "admin", label="leaving")
    rotated = add_key(path, "acme", "query", label="rotating")
    service = Workers(
        [TRACK_NET], "--state-db", str(tmp_path / "state.sqlite3"), "--api-keys", str(path), "--public-docs"
    )
    try:
        clients = service.clients()
        for client in clients:
            for key in (revoked, rotated):
                assert client.post("/v1/warning", json=_query("truck"), headers=_auth(key)).status_code == 200
        assert _csws("keys", "revoke", "leaving", "--file", str(path)).returncode == 0
        new = _csws("keys", "rotate", "rotating", "--file", str(path)).stdout.strip()
        for client in clients:
            for key in (revoked, rotated):
                answer = _refused(client, key)
                assert answer.json()["detail"] == UNKNOWN_KEY
            assert client.post("/v1/warning", json=_query("truck"), headers=_auth(new)).status_code == 200
            assert client.post("/v1/warning", json=_query("truck")).json()["detail"] == MISSING_KEY
        for client in clients:
            client.close()
    finally:
        service.stop()
    assert os.stat(path).st_mode & 0o077 == 0
