"""Headless Chromium for the browser tests: where it is, how it starts, and a page that records what it did.

The tests need the Debian package ``chromium`` (``tests/system-packages.sh`` installs it); Playwright
drives it and downloads no browser. The ``browser`` fixture (``conftest.py``) starts one per module.
"""

from __future__ import annotations

from urllib.parse import urlsplit

from playwright.sync_api import Page

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
#: The longest a page may take to show what it is waiting for, ms.
WAIT_MS = 30_000


class Recorded:
    """A page with everything it requested, the size of every response body as received (compressed), and
    its console errors."""

    def __init__(self, browser, viewport: dict[str, int] | None = None) -> None:
        self.page: Page = browser.new_page(viewport=viewport or {"width": 1200, "height": 800})
        self.urls: list[str] = []
        self.errors: list[str] = []
        self.body_sizes: list[int] = []
        self.page.on("requestfinished", lambda request: self.body_sizes.append(request.sizes()["responseBodySize"]))
        self.page.on("request", lambda request: self.urls.append(request.url))
        self.page.on("console", lambda message: message.type == "error" and self.errors.append(message.text))
        self.page.on("pageerror", lambda error: self.errors.append(str(error)))
        self.page.on("requestfailed", lambda request: self.errors.append(f"failed: {request.url}"))

    def assert_offline(self) -> None:
        """Nothing left the machine: every request went to the loopback service (or to the page's own
        ``data:`` and ``blob:`` contents), and nothing failed."""
        remote = [
            url
            for url in self.urls
            if urlsplit(url).scheme not in ("data", "blob") and urlsplit(url).hostname != "127.0.0.1"
        ]
        assert self.urls and not remote, remote
        assert not self.errors, self.errors
