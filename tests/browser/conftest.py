"""Browser tests: pytest-playwright driving Debian's chromium (never a downloaded browser).

* The browser is ``/usr/bin/chromium`` (``CHROMIUM`` overrides it); ``.ci/run`` installs it
  with apt-get when missing. Absent locally: the tests are skipped with a loud reason;
  absent with ``CI`` set: they fail.
* Playwright's sync API keeps an asyncio loop running in the main thread while it lives, and
  Django's ORM refuses to run "in an async context" then. The documented workaround
  (``DJANGO_ALLOW_ASYNC_UNSAFE``) is set for this package only, and Playwright itself is
  started per module instead of per session, so the rest of the suite runs with the check on.
* Screenshots of every page go to ``test-artifacts/browser/`` (ignored by git);
  ``UPDATE_SCREENSHOTS=1`` also refreshes the committed copies in ``docs/screenshots/``.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "test-artifacts" / "browser"
MISSING = (
    f"!!! CHROMIUM NOT FOUND at {CHROMIUM}: the browser tests are SKIPPED. "
    "Install it with `apt-get install chromium` (never `playwright install`); "
    "with CI set this is a failure."
)


def _chromium_present() -> bool:
    return os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK)


@pytest.fixture(autouse=True, scope="module")
def _chromium_required() -> None:
    """Runs before Playwright starts: skip loudly, or fail under CI, without a browser."""
    if _chromium_present():
        return
    if os.environ.get("CI"):
        pytest.fail(MISSING.replace("SKIPPED", "REQUIRED (CI is set)"), pytrace=False)
    pytest.skip(MISSING)


@pytest.fixture(autouse=True, scope="module")
def _async_unsafe_allowed(_chromium_required: None) -> Iterator[None]:
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("DJANGO_ALLOW_ASYNC_UNSAFE", "true")
        yield


@pytest.fixture(scope="session")
def browser_type_launch_args(browser_type_launch_args: dict) -> dict:
    return {**browser_type_launch_args, "executable_path": CHROMIUM}


@pytest.fixture(scope="module")
def playwright(_async_unsafe_allowed: None):
    """Per module (the plugin's is per session), so its event loop ends with the module."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        yield pw


@pytest.fixture(scope="module")
def browser(playwright, browser_type_launch_args: dict):
    browser = playwright.chromium.launch(**browser_type_launch_args)
    yield browser
    browser.close()


@pytest.fixture(scope="module")
def browser_context_args() -> dict:
    # Not the plugin's: that one needs its own session ``device`` fixture, which
    # tests/conftest.py's ``device`` (a comparison's Device) overrides.
    return {
        "viewport": {"width": 1280, "height": 860},
        "accept_downloads": True,
        "locale": "en-GB",
        "timezone_id": "UTC",
    }


@pytest.fixture
def shots(request: pytest.FixtureRequest):
    """``shots(page, name, publish=False)``: a full-page PNG in test-artifacts/browser/<test>/;
    with ``publish`` and ``UPDATE_SCREENSHOTS=1`` also a copy in docs/screenshots/."""
    folder = ARTIFACTS / request.node.name
    folder.mkdir(parents=True, exist_ok=True)
    update = bool(os.environ.get("UPDATE_SCREENSHOTS"))

    def take(page, name: str, *, publish: bool = False) -> Path:
        path = folder / f"{name}.png"
        page.screenshot(path=path, full_page=True)
        if publish and update:
            # The body, not the viewport: no blank band under a short page.
            page.locator("body").screenshot(path=ROOT / "docs" / "screenshots" / f"{name}.png")
        return path

    return take


class ConsoleErrors(list):
    """Console errors and uncaught exceptions of the watched pages (CSP violations show up
    here as console errors)."""

    def watch(self, page) -> None:
        page.on("console", lambda message: self._console(page, message))
        page.on("pageerror", lambda error: self.append(f"{page.url}: {error}"))

    def _console(self, page, message) -> None:
        # The site has no favicon: Chromium's automatic request for it is not the page's.
        url = message.location.get("url", "")
        if message.type == "error" and not url.endswith("/favicon.ico"):
            self.append(f"{page.url}: {message.text}")


@pytest.fixture
def console_errors(page) -> ConsoleErrors:
    errors = ConsoleErrors()
    errors.watch(page)
    return errors
