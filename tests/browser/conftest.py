"""Fixtures for the browser tests: one headless Debian Chromium for the whole run."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import sync_playwright

from tests.browser.harness import (
    TEST_WEBGL,
    FrameLog,
    WebGLUnavailable,
    launch,
    new_context,
    webgl_renderer,
)
from tests.browser.page import SCREENSHOTS


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """Chromium with the tests' WebGL (``TEST_WEBGL``, llvmpipe unless told), checked once: a
    page that got another renderer, or none, would fail every test for a reason none names."""
    with sync_playwright() as p:
        b = launch(p, webgl=TEST_WEBGL)
        try:
            renderer = webgl_renderer(b)
            if TEST_WEBGL.lower() not in renderer.lower():
                raise WebGLUnavailable(f"asked for {TEST_WEBGL} WebGL, pages got {renderer!r}")
            yield b
        finally:
            b.close()


@pytest.fixture
def context(browser: Any) -> Iterator[Any]:
    ctx = new_context(browser, viewport={"width": 1100, "height": 720})
    ctx.set_default_timeout(60_000)  # software WebGL under load: a first draw can take 20 s
    try:
        yield ctx
    finally:
        ctx.close()


@pytest.fixture
def small(browser: Any) -> Iterator[Any]:
    """An 800 x 600 window for tests that measure no pixel and keep no screenshot (blinding,
    key state): 61 % of the pixels of 1100 x 720 for software WebGL to draw, leaving more of
    the cores to the server and the other pytest worker (the tests' own times are set by what
    they wait for: no faster within the noise of a shared machine). Wide enough for viser's
    desktop layout (its phone layout starts below 576 px)."""
    ctx = new_context(browser, viewport={"width": 800, "height": 600})
    ctx.set_default_timeout(60_000)
    try:
        yield ctx
    finally:
        ctx.close()


@pytest.fixture
def wide(browser: Any) -> Iterator[Any]:
    """A 1366 x 768 window, a common laptop screen: the size the page is tried at."""
    ctx = new_context(browser, viewport={"width": 1366, "height": 768})
    ctx.set_default_timeout(120_000)  # a first draw of the scene on a loaded machine
    try:
        yield ctx
    finally:
        ctx.close()


@pytest.fixture
def page_with_frames(context: Any) -> tuple[Any, FrameLog]:
    page = context.new_page()
    return page, FrameLog().attach(page)


@pytest.fixture(scope="session")
def screenshots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where the tests save their screenshots of each phase: a temporary folder, or the README's
    committed folder when run with ``UPDATE_SCREENSHOTS=1`` (so a test run leaves git clean)."""
    if os.environ.get("UPDATE_SCREENSHOTS") == "1":
        SCREENSHOTS.mkdir(exist_ok=True)
        return SCREENSHOTS
    return tmp_path_factory.mktemp("screenshots")
