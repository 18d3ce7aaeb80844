"""What a participant dragging the handle gets, idle and under load (``page_fps.py --drag``).

Two ways to drag the handle's sideways (y) arrow in headless Debian Chromium (software WebGL):

* **person**: pointer events at the person's own pace, 60 a second by the wall clock, sent with
  CDP ``Input.dispatchMouseEvent`` without waiting for the renderer (a mouse does not wait for
  the page either); the drag covers ``drag_px`` pixels (100) in ``--drag-s`` seconds (3);
* **scripted**: Playwright's ``mouse.move`` in ``steps``, each awaited, then a 150 ms wait, as
  ``tests/browser/harness.drag`` does (each ``mouse.move`` returns once the renderer has handled
  the event).

For each drag it prints the planned and actual duration (pointer: first to last move; server:
the gizmo target's first change to reaching its end within 1 mm), the target's lag behind the
pointer (every 10 ms: how long ago the pointer was where the server's newest target puts the
handle, computed from the camera as the handle's arrow does it: the point of the arrow's line
closest to the pointer's ray; a pose the page holds back grows it), the latency of each gizmo
pose the server received (its time minus the time the pointer was there), the latency to the
arm's end (gripper within 5 mm of the final target), the page's frames, pointer events and
pose sends a second during the move, how late the client's 50 ms send timer fired, and how
long each ``mouse.move`` (or CDP event) took to be acknowledged.

Load: ``--burners N`` starts N ``python -c 'while True: pass'`` at nice 0 for the loaded
windows (N = 0 measures idle only). Clocks: the server's receipt and the pointer's sends are
``time.monotonic()`` in this process; page times are mapped onto it from a round trip.
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import viser.transforms as vtf

from study.server.live.controls import LiveInput
from tests.browser.harness import CHROMIUM, CHROMIUM_ARGS, start_server
from tests.browser.page import AGREE

POINTER_HZ = 60.0
"""How often a person's mouse reports a position while it moves (60-125 Hz for most mice)."""

PAGE_PROBE_JS = """() => {
  const log = { moves: [], coalesced: 0, frames: [], sends: [], timers: [] };
  window.__drag = log;
  const later = window.setTimeout;  // how late the client's 50 ms send timer fires
  window.setTimeout = function (fn, ms, ...rest) {
    if (ms !== 50 || typeof fn !== "function") return later.call(this, fn, ms, ...rest);
    const t = performance.now();
    return later.call(this, (...a) => { log.timers.push([t, performance.now()]); fn(...a); },
                      ms, ...rest);
  };
  const post = Worker.prototype.postMessage;  // the client's messages go to its socket worker
  Worker.prototype.postMessage = function (data, ...rest) {
    const m = data && data.type === "send" ? data.message : null;
    if (m && m.type === "TransformControlsUpdateMessage") log.sends.push(performance.now());
    return post.call(this, data, ...rest);
  };
  window.addEventListener("pointermove", (e) => {
    log.moves.push([performance.now(), e.clientX, e.clientY]);
    log.coalesced += e.getCoalescedEvents ? e.getCoalescedEvents().length : 1;
  }, { capture: true });
  const frame = (t) => { log.frames.push(t); requestAnimationFrame(frame); };
  requestAnimationFrame(frame);
}"""


@dataclass
class Recorder:
    """The gizmo targets the server received and the gripper's positions, with their times."""

    targets: list[tuple[float, np.ndarray]] = field(default_factory=list)
    gripper: list[tuple[float, np.ndarray]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def install(self) -> None:
        """Wrap ``LiveInput.on_target`` (the call the handle's callback makes on arrival)."""
        original = LiveInput.on_target
        recorder = self

        def on_target(self: LiveInput, target: np.ndarray) -> None:
            with recorder.lock:
                recorder.targets.append((time.monotonic(), np.array(target, float)))
            original(self, target)

        LiveInput.on_target = on_target  # type: ignore[method-assign]

    def poll_gripper(self, live: Any, stop: threading.Event, *, hz: float = 100.0) -> None:
        while not stop.is_set():
            run = live.run
            if run is not None:
                g = np.array(run.trial.poses().gripper, float)
                with self.lock:
                    self.gripper.append((time.monotonic(), g))
            time.sleep(1.0 / hz)

    def since(self, t0: float) -> tuple[list[tuple[float, np.ndarray]], list]:
        with self.lock:
            return (
                [x for x in self.targets if x[0] >= t0],
                [x for x in self.gripper if x[0] >= t0],
            )


def _ray(camera: Any, box: dict[str, float], px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World ray (origin, unit direction) through page pixel ``px`` (OpenCV camera axes)."""
    x = (px[0] - box["x"]) * camera.image_width / box["width"]
    y = (px[1] - box["y"]) * camera.image_height / box["height"]
    f = (camera.image_height / 2) / np.tan(camera.fov / 2)
    d = np.array([(x - camera.image_width / 2) / f, (y - camera.image_height / 2) / f, 1.0])
    rot = vtf.SO3(np.asarray(camera.wxyz)).as_matrix()
    d = rot @ d
    return np.asarray(camera.position, float), d / np.linalg.norm(d)


def _along(origin: np.ndarray, axis: np.ndarray, ray: tuple[np.ndarray, np.ndarray]) -> float:
    """Parameter t of the point origin + t axis closest to ``ray`` (the arrow's drag rule)."""
    c, d = ray
    w0 = origin - c
    b, dd, ee = float(axis @ d), float(axis @ w0), float(d @ w0)
    return (b * ee - dd) / (1.0 - b * b)


def _project(camera: Any, box: dict[str, float], point: np.ndarray) -> np.ndarray:
    rot = vtf.SO3(np.asarray(camera.wxyz)).as_matrix()
    pc = rot.T @ (np.asarray(point, float) - np.asarray(camera.position))
    f = (camera.image_height / 2) / np.tan(camera.fov / 2)
    x = f * pc[0] / pc[2] + camera.image_width / 2
    y = f * pc[1] / pc[2] + camera.image_height / 2
    return np.array(
        [
            box["x"] + x * box["width"] / camera.image_width,
            box["y"] + y * box["height"] / camera.image_height,
        ]
    )


async def _clock_offset(page: Any) -> float:
    """``time.monotonic() - performance.now() / 1000`` from the tightest of a few round trips."""
    best = (np.inf, 0.0)
    for _ in range(5):
        t0 = time.monotonic()
        now = float(await page.evaluate("() => performance.now()"))
        t1 = time.monotonic()
        best = min(best, (t1 - t0, (t0 + t1) / 2 - now / 1000))
    return best[1]


async def _join(page: Any, url: str, code: str) -> None:
    await page.goto(url)
    await page.locator("svg.tabler-icon-cloud-check").first.wait_for(timeout=60_000)
    await page.get_by_text("Please type the join code").wait_for()
    field_ = page.locator(
        "xpath=//label[text()='Join code']/ancestor::div[contains(@class,"
        " 'mantine-Flex-root')][1]//input"
    )
    await field_.click()
    await page.keyboard.type(code.lower(), delay=40)
    await page.get_by_role("button", name="Join").click()
    await page.get_by_role("button", name=AGREE).click()
    await page.get_by_role("button", name="Start").wait_for()
    await page.wait_for_timeout(1000)
    await page.get_by_role("button", name="Start").click()
    await page.get_by_role("button", name="Close the gripper (G)").wait_for()


async def _wait_still(read: Any, *, tol: float = 5e-4, still_s: float = 0.4, timeout=20.0):
    ref, since = np.asarray(read(), float), time.monotonic()
    end = since + timeout
    while time.monotonic() < end:
        await asyncio.sleep(0.05)
        value = np.asarray(read(), float)
        if np.abs(value - ref).max() > tol:
            ref, since = value, time.monotonic()
        elif time.monotonic() - since >= still_s:
            return True
    return False


@dataclass
class Drag:
    """One drag's plan: grab at ``start`` (page pixels), end at ``end``; the arrow's line."""

    start: np.ndarray
    end: np.ndarray
    origin: np.ndarray
    axis: np.ndarray
    camera: Any
    box: dict[str, float]
    target0: np.ndarray

    def target_at(self, px: np.ndarray) -> float:
        """The target's coordinate along the axis with the pointer at ``px``."""
        t0 = _along(self.origin, self.axis, _ray(self.camera, self.box, self.start))
        t = _along(self.origin, self.axis, _ray(self.camera, self.box, px))
        return float(self.target0 @ self.axis + (t - t0))


async def _plan(page: Any, live: Any, *, px: float, sign: float) -> Drag:
    """A drag of the y arrow (sideways on the screen) by ``px`` page pixels, ``sign`` way."""
    from study.server.page_handle import HANDLE_OFFSET_M, HANDLE_PX

    cam = live.page.client.camera
    box = await page.locator("canvas").first.bounding_box()
    origin = np.asarray(live.page.handle.gizmo.position, float)
    axis = np.array([0.0, 1.0, 0.0])
    o = _project(cam, box, origin)
    # pixels per metre at the handle: one centimetre along the axis, projected
    per_m = float(np.linalg.norm(_project(cam, box, origin + 0.01 * axis) - o)) / 0.01
    tip = _project(cam, box, origin + HANDLE_PX / per_m * axis)
    direction = (tip - o) / np.linalg.norm(tip - o)
    grab = o + 0.5 * (tip - o)  # the arrows look shorter than HANDLE_PX: mid-arrow
    return Drag(
        start=grab,
        end=grab + sign * px * direction,
        origin=origin,
        axis=axis,
        camera=cam,
        box=box,
        target0=origin - np.array([0.0, 0.0, HANDLE_OFFSET_M]),
    )


def _mouse(kind: str, p: np.ndarray, *, buttons: int) -> dict[str, Any]:
    return {
        "type": kind,
        "x": float(p[0]),
        "y": float(p[1]),
        "button": "left",
        "buttons": buttons,
        "clickCount": 1 if kind != "mouseMoved" else 0,
    }


async def _person(page: Any, cdp: Any, drag: Drag, seconds: float) -> dict[str, Any]:
    """Hover, press, move at :data:`POINTER_HZ` by the wall clock without waiting for the page,
    hold 0.5 s, release. Returns the pointer's (time, pixel) and each send's ack delay."""
    pending: list[asyncio.Future] = []
    acks: list[float] = []

    def send(kind: str, p: np.ndarray, buttons: int) -> None:
        t = time.monotonic()
        fut = asyncio.ensure_future(
            cdp.send("Input.dispatchMouseEvent", _mouse(kind, p, buttons=buttons))
        )
        fut.add_done_callback(lambda _f: acks.append(time.monotonic() - t))
        pending.append(fut)

    send("mouseMoved", drag.start + np.array([-6.0, 6.0]), 0)
    await asyncio.sleep(0.3)
    send("mouseMoved", drag.start, 0)
    await asyncio.sleep(0.5)
    send("mousePressed", drag.start, 1)
    await asyncio.sleep(0.5)
    acks.clear()
    n = max(1, round(seconds * POINTER_HZ))
    moves: list[tuple[float, np.ndarray]] = []
    t0 = time.monotonic()
    for k in range(1, n + 1):
        await asyncio.sleep(max(0.0, t0 + k / POINTER_HZ - time.monotonic()))
        p = drag.start + (drag.end - drag.start) * k / n
        moves.append((time.monotonic(), p))
        send("mouseMoved", p, 1)
    await asyncio.sleep(0.5)
    send("mouseReleased", drag.end, 0)
    await asyncio.gather(*pending)
    return {"moves": moves, "acks": list(acks)}


async def _scripted(page: Any, drag: Drag, steps: int) -> dict[str, Any]:
    """``tests/browser/harness.drag``'s moves: each ``mouse.move`` awaited, then 150 ms."""
    m = page.mouse
    await m.move(*(drag.start + np.array([-6.0, 6.0])))
    await page.wait_for_timeout(300)
    await m.move(*drag.start)
    await page.wait_for_timeout(500)
    await m.down()
    await page.wait_for_timeout(500)
    moves: list[tuple[float, np.ndarray]] = []
    acks: list[float] = []
    for k in range(1, steps + 1):
        p = drag.start + (drag.end - drag.start) * k / steps
        t = time.monotonic()
        moves.append((t, p))
        await m.move(float(p[0]), float(p[1]))
        acks.append(time.monotonic() - t)
        await page.wait_for_timeout(150)
    await page.wait_for_timeout(400)
    await m.up()
    return {"moves": moves, "acks": acks}


def _analyse(
    drag: Drag,
    pointer: dict[str, Any],
    targets: list[tuple[float, np.ndarray]],
    gripper: list[tuple[float, np.ndarray]],
    page_log: dict[str, Any],
    offset: float,
) -> dict[str, Any]:
    """The figures of one drag (module docstring). Progress along the drag is measured as a
    fraction of its length (the pointer's from the camera geometry, the server's from its last
    target), so a small error of the geometry's scale (2 % at most seen) cancels."""
    moves = pointer["moves"]
    tp = np.array([t for t, _ in moves])
    v0 = float(drag.target0 @ drag.axis)
    # the pointer's progress over time (from the press: 0), monotonic by construction
    gp = np.array([drag.target_at(p) for _, p in moves]) - v0
    prog_t = np.concatenate([[tp[0] - 1.0 / POINTER_HZ], tp])
    prog_u = np.maximum.accumulate(np.concatenate([[0.0], gp / gp[-1]]))
    ts = np.array([t for t, _ in targets])
    vs = np.array([float(x @ drag.axis) for _, x in targets]) - v0
    row: dict[str, Any] = {"pointer_s": round(float(tp[-1] - tp[0]), 2), "targets": len(ts)}
    if len(ts) == 0 or abs(vs[-1]) < 1e-3:
        return row  # the handle was not grabbed
    us = vs / vs[-1]
    moving = (us > 0.01) & (us < 0.999)
    lat = ts[moving] - np.interp(us[moving], prog_u, prog_t)
    # the target's lag behind the pointer, every 10 ms from the first move until the target is
    # at its end: how far back in the pointer's path the server's newest target lies (a pose
    # held back by the page grows it; per received pose it would not show)
    grid = np.arange(tp[0], ts[np.abs(vs - vs[-1]) < 1e-3][0], 0.01)
    held = np.searchsorted(ts, grid, side="right") - 1
    u_now = np.where(held >= 0, us[np.maximum(held, 0)], 0.0)
    lag = grid - np.interp(np.minimum(u_now, 1.0), prog_u, prog_t, left=tp[0])
    started = ts[us > 0.01][0]
    reached = ts[np.abs(vs - vs[-1]) < 1e-3][0]
    final_target = targets[-1][1]
    g_t = np.array([t for t, _ in gripper])
    g_d = np.array([float(np.linalg.norm(g - final_target)) for _, g in gripper])
    arm = g_t[(g_t > tp[-1]) & (g_d < 0.005)]
    # the page's side: pointer events dispatched to the page and frames drawn while it moved,
    # and the delay from the pointer to the page (the dispatched event's position)
    pm = np.array([t / 1000 + offset for t, _, _ in page_log["moves"]])
    pu = np.array(
        [(drag.target_at(np.array([x, y])) - v0) / gp[-1] for _, x, y in page_log["moves"]]
    )
    fr = np.array([t / 1000 + offset for t in page_log["frames"]])
    inside = (pm >= tp[0]) & (pu > 0.01) & (pu < 0.999)
    to_page = pm[inside] - np.interp(pu[inside], prog_u, prog_t)
    sends = np.array([t / 1000 + offset for t in page_log["sends"]])
    # each server target's page send: the last send before it arrived
    k = np.searchsorted(sends, ts[moving]) - 1
    ok = k >= 0
    page_to_server = ts[moving][ok] - sends[k[ok]]
    late = np.array(
        [b - a - 50.0 for a, b in page_log["timers"] if tp[0] <= a / 1000 + offset <= tp[-1]]
    )
    dur = float(tp[-1] - tp[0])
    n_pm = int(np.sum((pm >= tp[0]) & (pm <= tp[-1])))
    n_fr = int(np.sum((fr >= tp[0]) & (fr <= tp[-1])))
    frame_gaps = np.diff(fr[(fr >= tp[0]) & (fr <= tp[-1])]) * 1e3
    ms = lambda a, q: round(float(np.percentile(a, q)) * 1e3) if len(a) else None  # noqa: E731
    row.update(
        server_s=round(float(reached - started), 2),
        end_lag_ms=round(float(reached - tp[-1]) * 1e3),
        arm_end_lag_ms=round(float(arm[0] - tp[-1]) * 1e3) if len(arm) else None,
        lag_ms_median=ms(lag, 50),
        lag_ms_p99=ms(lag, 99),
        lag_ms_max=ms(lag, 100),
        latency_ms_median=ms(lat, 50),
        latency_ms_p99=ms(lat, 99),
        to_page_ms_median=ms(to_page, 50),
        to_page_ms_p99=ms(to_page, 99),
        page_sends_per_s=round(float(np.sum((sends >= tp[0]) & (sends <= tp[-1])) / dur), 1),
        page_to_server_ms_median=ms(page_to_server, 50),
        page_to_server_ms_p99=ms(page_to_server, 99),
        timer_50ms_late_ms_median=round(float(np.median(late))) if len(late) else None,
        timer_50ms_late_ms_max=round(float(late.max())) if len(late) else None,
        server_targets_per_s=round(float(np.sum((ts >= tp[0]) & (ts <= tp[-1])) / dur), 1),
        page_pointer_events_per_s=round(n_pm / dur, 1),
        page_fps=round(n_fr / dur, 1),
        page_frame_gap_ms_max=round(float(frame_gaps.max())) if len(frame_gaps) else None,
        scale_error_pct=round(float(gp[-1] / vs[-1] - 1.0) * 100, 1),
        move_ack_ms_median=round(float(np.median(pointer["acks"])) * 1e3)
        if pointer["acks"]
        else None,
        move_ack_ms_max=round(float(np.max(pointer["acks"])) * 1e3) if pointer["acks"] else None,
    )
    return row


def _burn(n: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def _stop(burners: list[subprocess.Popen]) -> None:
    for b in burners:
        b.terminate()
    for b in burners:
        b.wait()


async def measure(
    *,
    viewport: str = "1366x768",
    burners: int = 2,
    repeats: int = 3,
    drag_s: float = 3.0,
    drag_px: float = 100.0,
    steps: int = 12,
) -> dict[str, Any]:
    """Drags idle, then with ``burners`` busy loops: the person's and the scripted."""
    import os

    from playwright.async_api import async_playwright

    recorder = Recorder()
    recorder.install()
    width, height = (int(v) for v in viewport.split("x"))
    results: dict[str, Any] = {"viewport": viewport, "burners": burners, "drags": []}
    async with async_playwright() as p:
        browser = await p.chromium.launch(
            executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True
        )
        rs = start_server(tempfile.mkdtemp(prefix="bench-drag-"), time_limit_s=900.0)
        stop = threading.Event()
        try:
            srv = rs.server
            code = srv.enrol("B01")
            srv.act(code, "start")
            live = srv.session(code)
            page = await browser.new_page(viewport={"width": width, "height": height})
            page.set_default_timeout(120_000)
            await page.add_init_script(f"({PAGE_PROBE_JS})()")
            await _join(page, rs.url, code)
            cdp = await page.context.new_cdp_session(page)
            await page.wait_for_timeout(3000)
            threading.Thread(target=recorder.poll_gripper, args=(live, stop), daemon=True).start()
            sign = 1.0
            for load in ("idle", "load") if burners else ("idle",):
                burning = _burn(burners) if load == "load" else []
                try:
                    if burning:
                        await asyncio.sleep(2.0)
                    for k in range(repeats):
                        for how in ("person", "scripted"):
                            await _wait_still(lambda: live.run.trial.poses().gripper)
                            await _wait_still(lambda: live.page.client.camera.position)
                            await _wait_still(lambda: live.page.handle.gizmo.position)
                            drag = await _plan(page, live, px=drag_px, sign=sign)
                            sign = -sign  # back and forth: the arm stays in its reach
                            offset = await _clock_offset(page)
                            await page.evaluate(
                                "() => { __drag.moves = []; __drag.frames = [];"
                                " __drag.sends = []; __drag.timers = []; __drag.coalesced = 0; }"
                            )
                            t0 = time.monotonic()
                            if how == "person":
                                pointer = await _person(page, cdp, drag, drag_s)
                            else:
                                pointer = await _scripted(page, drag, steps)
                            await asyncio.sleep(1.0)
                            await _wait_still(lambda: live.run.trial.poses().gripper)
                            page_log = await page.evaluate("() => __drag")
                            targets, gripper = recorder.since(t0)
                            row = _analyse(drag, pointer, targets, gripper, page_log, offset)
                            row.update(
                                how=how,
                                load=load,
                                repeat=k,
                                load_average_1min=round(os.getloadavg()[0], 2),
                            )
                            print(row, flush=True)
                            results["drags"].append(row)
                finally:
                    _stop(burning)
            await browser.close()
        finally:
            stop.set()
            rs.stop()
    return results


def summary(results: dict[str, Any]) -> list[str]:
    """One line per (how, load): medians over the drags that grabbed the handle."""
    lines = []
    rows = results["drags"]
    for how in ("person", "scripted"):
        for load in ("idle", "load"):
            sel = [r for r in rows if r["how"] == how and r["load"] == load]
            if not sel:
                continue

            def med(key: str, sel=sel) -> float | None:
                v = [r[key] for r in sel if r.get(key) is not None]
                return round(float(np.median(v)), 1) if v else None

            grabbed = sum(1 for r in sel if r.get("server_s") is not None)
            lines.append(
                f"{how} drag, {load} (load average {med('load_average_1min')}; {grabbed} of"
                f" {len(sel)} grabbed): pointer moved {med('pointer_s')} s, the server's target"
                f" {med('server_s')} s; the target lags the pointer by {med('lag_ms_median')} ms"
                f" (p99 {med('lag_ms_p99')}, max {med('lag_ms_max')}); each pose received"
                f" median"
                f" {med('latency_ms_median')} ms after the pointer was there, p99"
                f" {med('latency_ms_p99')} ms (pointer ->"
                f" page {med('to_page_ms_median')} / {med('to_page_ms_p99')} ms); target at"
                f" its end {med('end_lag_ms')} ms after the pointer, arm"
                f" {med('arm_end_lag_ms')} ms; page {med('page_fps')} frames/s (longest gap"
                f" {med('page_frame_gap_ms_max')} ms), {med('page_pointer_events_per_s')}"
                f" pointer events/s, {med('page_sends_per_s')} sends/s (send -> server"
                f" {med('page_to_server_ms_median')} / {med('page_to_server_ms_p99')} ms),"
                f" server {med('server_targets_per_s')} targets/s; the client's 50 ms send"
                f" timer late by {med('timer_50ms_late_ms_median')} ms (max"
                f" {med('timer_50ms_late_ms_max')}); a move"
                f" acknowledged in {med('move_ack_ms_median')} ms (max {med('move_ack_ms_max')})"
            )
    return lines
