"""Pytest plugin (loaded by tests/conftest.py): one Chromium for every browser test of a run,
and a fresh context (cookies, cache, viewport 1500x860) for each test module."""

from __future__ import annotations

import pytest

from browser_util import chromium_browser, new_context


@pytest.fixture(scope="session")
def chromium_session():
    """The run's one headless Chromium (skips when Playwright or Debian's chromium is missing)."""
    pytest.importorskip("playwright.sync_api")
    try:
        with chromium_browser() as browser:
            yield browser
    except FileNotFoundError as e:
        pytest.skip(str(e))


@pytest.fixture(scope="module")
def browser(chromium_session):
    """A browser context of its own for one test module (``browser.new_page()``)."""
    ctx = new_context(chromium_session)
    yield ctx
    ctx.close()
