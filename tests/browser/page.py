"""What a participant does in a page, for the browser tests: open the page (reloading once if it
never connects), join with a code, press and hold keys with auto-repeat, wait for frames to
settle, save a screenshot; and where a world point lands on the page (pixels, pixels per metre)."""

from __future__ import annotations

import io
import time
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from playwright.sync_api import expect

from tests.browser.harness import (
    project,
    wait_until,
)

AGREE = "I have read this and agree to take part"


def wait_connected(page: Any, *, timeout_ms: float = 30_000) -> None:
    """Wait for viser's green cloud, the sign a participant sees that the tab is connected.
    Not the word "Connected": the page names itself in that place as soon as its first
    messages arrive, so the word shows only for a moment (a loaded machine's browser may
    never see it)."""
    page.locator("svg.tabler-icon-cloud-check").first.wait_for(timeout=timeout_ms)


def connect_page(page: Any, url: str) -> None:
    """Open ``url`` and wait until it is connected (:func:`wait_connected`). A page still not
    connected after 30 s is reloaded once, as a person would; what it showed is printed, and a
    second failure fails the test with it."""
    page.goto(url)
    try:
        wait_connected(page)
        return
    except Exception:
        shown = page.inner_text("body")[:300]
        print(f"not connected after 30 s, reloading; the page showed: {shown!r}")
    page.reload()
    try:
        wait_connected(page)
    except Exception as exc:
        shown = page.inner_text("body")[:300]
        raise AssertionError(f"not connected after a reload; the page showed: {shown!r}") from exc


def start_first_run(study: Any, page: Any, *, participant: str = "P01") -> Any:
    """Enrol ``participant`` and take ``page`` through join, consent and Start into the first
    (practice) run, as the participant would; returns the live session once its run and scene
    are up."""
    srv = study.server
    code = srv.enrol(participant)
    srv.act(code, "start")
    live = srv.session(code)
    connect_page(page, study.url)
    join(page, code)
    page.get_by_role("button", name=AGREE).click()
    page.get_by_role("button", name="Start").wait_for()
    settle_frames(page)
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    assert wait_until(lambda: live.run is not None and live.scene_view is not None)
    return live


def text_input(page: Any, label: str) -> Any:
    """viser's text input next to ``label`` (its <label for> does not name the input)."""
    return page.locator(
        f"xpath=//label[text()='{label}']/ancestor::div[contains(@class, 'mantine-Flex-root')][1]"
        "//input"
    )


def join(page: Any, code: str, *, then: str | None = AGREE) -> None:
    """Type the join code as a participant would and wait for the button ``then``."""
    page.get_by_text("Please type the join code").wait_for()
    field = text_input(page, "Join code")
    field.click()
    field.fill("")
    page.keyboard.type(code.lower(), delay=40)  # typed into the field: no key reaches the arm
    page.get_by_role("button", name="Join").click()
    if then is not None:
        page.get_by_role("button", name=then).wait_for()


def hold(page: Any, key: str, seconds: float, *, repeat_hz: float = 30.0) -> None:
    """Hold ``key`` for ``seconds`` with auto-repeat, as a keyboard does."""
    page.keyboard.down(key)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        page.wait_for_timeout(1000 / repeat_hz)
        page.keyboard.down(key)  # a repeat: KeyboardEvent.repeat is true
    page.keyboard.up(key)


SCREENSHOTS = Path(__file__).resolve().parent / "screenshots"
"""The README's committed screenshots (written with ``UPDATE_SCREENSHOTS=1``)."""

SETTLED_JS = """async (limitMs) => {
  const frame = () => new Promise((r) => requestAnimationFrame(r));
  const end = performance.now() + limitMs;
  const moving = () => document.getAnimations().some((a) => a.playState === "running"
    && a.effect && a.effect.getComputedTiming().iterations !== Infinity);
  await frame();
  while (moving() && performance.now() < end) await frame();
  await frame();
}"""
"""Wait for the page's finite CSS transitions and animations (a notice sliding in, a button
changing colour) to end, at most ``limitMs``, then for one more frame: what a screenshot shows
is what the participant sees once the screen is still."""


def settled(page: Any, *, limit_ms: float = 600) -> None:
    """Wait until the page's transitions end (:data:`SETTLED_JS`): an event, not a fixed
    wait (a fixed 300 ms before each screenshot cost about 15 s a run of the browser tests)."""
    page.evaluate(SETTLED_JS, limit_ms)


def screenshot(page: Any, folder: Path, name: str, *, colors: int = 96) -> None:
    """Save a screenshot of what the participant sees once the page is still (:func:`settled`).
    For the README (``folder`` is :data:`SCREENSHOTS`) a small PNG with a ``colors`` palette;
    elsewhere the browser's PNG as it is (a palette costs 0.1-0.3 CPU s a screenshot). The
    viewer's own notices (software WebGL) are the page's to hide (``study.server.page_head``):
    a screenshot shows what the participant sees. 96 colours merge the box's orange with the
    table's in the view from above (the box looks hollow): 256 keep it."""
    settled(page)
    t = time.monotonic()
    png = page.screenshot()
    print(f"screenshot {name}: {time.monotonic() - t:.1f} s")
    path = folder / f"{name}.png"
    if folder.resolve() != SCREENSHOTS:
        path.write_bytes(png)
        return
    image = Image.open(io.BytesIO(png)).convert("RGB")
    image.quantize(colors=colors, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)


def settle_frames(page: Any, *, rounds: int = 2) -> None:
    """Wait until the browser draws frames quickly again (each screenshot waits for a frame)."""
    for _ in range(rounds):
        t = time.monotonic()
        page.screenshot()
        print(f"settle frame: {time.monotonic() - t:.1f} s")


def without_client_warning(text: str) -> str:
    """The page text minus the viser client's own software-rendering notice ("... check that
    hardware acceleration is enabled ..."), which the browser bundle shows by itself when WebGL
    runs in software; the server never sends it (the websocket check below covers that)."""
    lines = text.splitlines()
    return "\n".join(ln for ln in lines if "WebGL" not in ln and "hardware acceleration" not in ln)


def canvas_box(page: Any) -> dict[str, float]:
    """The scene canvas's box on the page (CSS pixels). Each call waits for the page's main
    thread (up to a second when software WebGL is busy): a caller placing several points at
    one moment reads it once and passes it on as ``box``."""
    return page.locator("canvas").first.bounding_box()


def page_pixel(
    page: Any, camera: Any, point: np.ndarray, *, box: dict[str, float] | None = None
) -> np.ndarray:
    """Page pixel (CSS) of world ``point``: the camera's image scaled to the canvas on the page
    (viser lowers the canvas resolution when frames are slow); ``box``: the canvas's box,
    read now if not given."""
    x, y = project(camera, point)
    box = box or canvas_box(page)
    return np.array(
        [
            box["x"] + x * box["width"] / camera.image_width,
            box["y"] + y * box["height"] / camera.image_height,
        ]
    )


def pixels_per_m(
    page: Any, camera: Any, point: np.ndarray, *, box: dict[str, float] | None = None
) -> float:
    """Page pixels per metre across the line of sight at ``point`` (``box``: as for
    :func:`page_pixel`)."""
    rot = np.asarray(camera.wxyz)
    w, x, y, z = rot
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    depth = float((r.T @ (np.asarray(point) - np.asarray(camera.position)))[2])
    box = box or canvas_box(page)
    f = (box["height"] / 2) / np.tan(camera.fov / 2)
    return f / depth


def wait_camera_still(live: Any) -> None:
    """Wait until the tab has reported the same camera pose for half a second (the task view
    is set from the server; the tab reports where its camera is)."""
    last = None
    for _ in range(40):
        cam = live.page.client.camera
        now = (*np.round(cam.position, 4), *np.round(cam.wxyz, 4))
        if now == last:
            return
        last = now
        time.sleep(0.5)


def answer_all(page: Any, n_items: int, value: int) -> None:
    """Click ``value`` on each of the ``n_items`` rows, checking Continue waits for all."""
    cont = page.get_by_role("button", name="Continue")
    expect(cont).to_be_disabled()
    for k in range(n_items):
        page.get_by_role("button", name=str(value), exact=True).first.click()
        page.get_by_text(f"Your answer: {value}").nth(k).wait_for()
    expect(page.get_by_role("button", name=f"[{value}]", exact=True)).to_have_count(n_items)
    expect(cont).to_be_enabled()
    cont.click()
