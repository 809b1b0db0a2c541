"""The fleets' webhooks: the URLs that receive each fleet's events, and the secret that signs them.

The service's admin configures them (``csws webhooks add | list | remove``), and a fleet's admin its
own over the API (``/v1/webhooks``, :mod:`service.routes.webhooks`), so the service relays nothing
to a URL nobody trusted; both change one file beside the API key file (``webhooks.json`` there, or
``CSWS_WEBHOOKS_FILE``), each change under its lock and written at once. Its format::

    {"format": "csws-webhooks/1",
     "fleets": [{"fleet": "acme", "secret": "whsec_...", "urls": ["https://dispatch.example/csws"]}]}

Unlike the key file, it must keep each secret itself, to sign with: it is written readable by its
owner only. A fleet's secret is made with its first URL and printed that once; its further URLs
share it. A running service reads the file again when it changes (:class:`WebhookBook`).
"""

from __future__ import annotations

import fcntl
import json
import os
import secrets
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from csws.files import replace_json

from ..keys import FLEET_PATTERN
from .addresses import resolved_addresses

__all__ = [
    "WEBHOOKS_FORMAT",
    "Webhook",
    "WebhookBook",
    "DuplicateWebhook",
    "TooManyWebhooks",
    "UnknownWebhook",
    "add_webhook",
    "remove_webhook",
    "list_webhooks",
    "default_webhooks_file",
]

WEBHOOKS_FORMAT = "csws-webhooks/1"
#: Every secret starts with this, so that a leaked one is recognisable.
SECRET_PREFIX = "whsec_"
#: A running service looks at the file's status at most this often, s.
RELOAD_INTERVAL_S = 1.0


class DuplicateWebhook(ValueError):
    """The fleet has this URL among its webhooks already."""


class TooManyWebhooks(ValueError):
    """The fleet has as many webhooks as it may."""


class UnknownWebhook(ValueError):
    """The fleet has no such webhook."""


@dataclass(frozen=True)
class Webhook:
    """One URL of a fleet, and the fleet's secret that signs what it receives."""

    fleet: str
    url: str
    secret: str

    @property
    def sink(self) -> str:
        """The name its cursor, retries and dead letters go by."""
        return f"webhook {self.fleet} {self.url}"


def default_webhooks_file(api_keys_file: Path | None) -> Path | None:
    """The webhook file: ``$CSWS_WEBHOOKS_FILE``, else ``webhooks.json`` beside the API key file (None without)."""
    given = os.environ.get("CSWS_WEBHOOKS_FILE")
    if given:
        return Path(given)
    keys = api_keys_file or (Path(os.environ["CSWS_API_KEYS_FILE"]) if os.environ.get("CSWS_API_KEYS_FILE") else None)
    return keys.with_name("webhooks.json") if keys is not None else None


def _fleets(path: Path) -> list[dict]:
    """The fleets of a webhook file, checked; ValueError naming the file otherwise (no file: none)."""
    try:
        content = json.loads(path.read_text("utf-8"))
    except FileNotFoundError:
        return []
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a webhook file ({exc})") from None
    if not isinstance(content, dict) or content.get("format") != WEBHOOKS_FORMAT:
        raise ValueError(f"{path}: not a webhook file (expected format {WEBHOOKS_FORMAT!r})")
    fleets = content.get("fleets")
    valid = isinstance(fleets, list) and all(
        isinstance(entry, dict)
        and isinstance(entry.get("fleet"), str)
        and FLEET_PATTERN.fullmatch(entry["fleet"]) is not None
        and isinstance(entry.get("secret"), str)
        and len(entry["secret"]) >= 16
        and isinstance(entry.get("urls"), list)
        and all(isinstance(url, str) for url in entry["urls"])
        for entry in fleets or []
    )
    if not valid:
        raise ValueError(f"{path}: each fleet needs a name, a secret of 16+ characters and a list of URLs")
    return list(fleets or [])


def _write(path: Path, fleets: list[dict]) -> None:
    """Write the webhook file at once (a reader sees the old file or the new one), readable by its owner only."""
    replace_json(path, {"format": WEBHOOKS_FORMAT, "fleets": fleets})


@contextmanager
def _changing(path: Path) -> Iterator[None]:
    """Hold the webhook file's lock (``.NAME.lock`` beside it) while it is read and written again, so that two
    changes at once (the command line, the API in several workers) do not lose one of them."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(f".{path.name}.lock"), "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def add_webhook(path: Path, fleet: str, url: str, allow_private: bool, max_urls: int | None = None) -> str | None:
    """Add ``url`` to the webhooks of ``fleet``; the fleet's new secret when this is its first URL, else None.

    Parameters
    ----------
    max_urls
        The most URLs the fleet may have (None: no bound), so that one fleet's events cannot fan out without end.

    Raises
    ------
    ValueError
        For a bad fleet name, a URL already there (:class:`DuplicateWebhook`), a fleet with ``max_urls`` already
        (:class:`TooManyWebhooks`), a file that is not a webhook file,
        or a URL the service may not reach (:class:`service.push.addresses.UnsafeTarget`, checked now and at every
        connection).
    """
    if FLEET_PATTERN.fullmatch(fleet) is None:
        raise ValueError(f"fleet must be 1-64 letters, digits, '_', '.' or '-', got {fleet!r}")
    resolved_addresses(url, allow_private)
    with _changing(path):
        return _added(path, fleet, url, max_urls)


def _added(path: Path, fleet: str, url: str, max_urls: int | None) -> str | None:
    """Add ``url`` to the webhooks of ``fleet`` in the file, under its lock; the fleet's new secret or None."""
    fleets = _fleets(path)
    entry = next((entry for entry in fleets if entry["fleet"] == fleet), None)
    secret = None
    if entry is None:
        secret = SECRET_PREFIX + secrets.token_urlsafe(32)
        entry = {"fleet": fleet, "secret": secret, "urls": []}
        fleets.append(entry)
    if url in entry["urls"]:
        raise DuplicateWebhook(f"{path}: fleet {fleet!r} has the webhook {url!r} already")
    if max_urls is not None and len(entry["urls"]) >= max_urls:
        raise TooManyWebhooks(f"{path}: fleet {fleet!r} has {max_urls} webhooks, the most it may have")
    entry["urls"].append(url)
    _write(path, fleets)
    return secret


def remove_webhook(path: Path, fleet: str, url: str) -> None:
    """Take ``url`` out of the webhooks of ``fleet`` (its secret goes with its last URL).

    Raises
    ------
    ValueError
        When the fleet has no such webhook (:class:`UnknownWebhook`), or the file is not a webhook file.
    """
    with _changing(path):
        fleets = _fleets(path)
        entry = next((entry for entry in fleets if entry["fleet"] == fleet and url in entry["urls"]), None)
        if entry is None:
            raise UnknownWebhook(f"{path}: fleet {fleet!r} has no webhook {url!r} (see csws webhooks list)")
        entry["urls"].remove(url)
        _write(path, [entry for entry in fleets if entry["urls"]])


def list_webhooks(path: Path) -> list[Webhook]:
    """The webhooks of the file, fleet by fleet, in the file's order."""
    return [Webhook(entry["fleet"], url, entry["secret"]) for entry in _fleets(path) for url in entry["urls"]]


class WebhookBook:
    """The webhooks of a file, read again when the file changes (at most every :data:`RELOAD_INTERVAL_S`).

    A file that has become unreadable leaves the webhooks last read in force, and :attr:`reload_error` says why.
    """

    def __init__(self, path: Path, reload_interval_s: float = RELOAD_INTERVAL_S) -> None:
        self.path = path
        self.reload_interval_s = reload_interval_s
        self.reload_error: str | None = None
        self._status: tuple[int, int, int] | None = None
        self._webhooks: list[Webhook] = []
        self._checked_s = -float("inf")

    def webhooks(self) -> list[Webhook]:
        """The webhooks in force."""
        now_s = time.monotonic()
        if now_s - self._checked_s >= self.reload_interval_s:
            self._checked_s = now_s
            self._refresh()
        return self._webhooks

    def _refresh(self) -> None:
        """Read the file again if its inode, size or modification time changed."""
        try:
            status = os.stat(self.path)
            key: tuple[int, int, int] | None = (status.st_ino, status.st_size, status.st_mtime_ns)
        except OSError:
            key = None
        if key == self._status:
            return
        try:
            self._webhooks = list_webhooks(self.path)
        except ValueError as exc:
            self.reload_error = str(exc)
            return
        self._status, self.reload_error = key, None
