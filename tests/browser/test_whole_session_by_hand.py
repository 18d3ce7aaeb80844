"""Two whole sessions at 1366 x 768, one with the mouse alone and one with the keys alone.

A full session for this purpose is every kind of screen a participant meets, in the protocol's
order, and every target reached and lifted: join, consent, the questions about the participant
(four dropdowns and a number), one practice run (the mug), the ratings after practice, the box
on the table (easy), the attention check between tasks, the box at the reach's edge (hard: the
arm must help), the ratings after each run, the closing comment and the data-retention question,
the debrief and the end. The protocol copy (``tests.protocol_copies.each_target_once``) keeps
the paper's scenes, policy, confidence and timid arbitration, and the correct prediction only:
each target once. Which mode and which correctness do not matter to what is tried here (can a
person see and do it), and the full 2 x 2 x 2 would cost eight more runs per session.

The mouse session drags the handle as a person drags (pressed, moved a few pixels at a time,
let go): the table-plane square over the target, then the up arrow down to it, correcting
after each drag by what the screen shows (the positions the server holds, as the gripper is
drawn from them), and clicks the grasp button and every answer. It types twice: the join code
and the hours of gaming (a number); the optional comment is left empty. The keys session holds
W/S, A/D and R/F with auto-repeat for seconds, presses G, moves between buttons with Tab,
presses them with Enter, opens each dropdown with the arrow keys and picks with Enter, and
types its comment. Nothing needs the mouse.

Screenshots at the start of each run, mid-reach (the mouse: half way through the first drag,
the button held; the keys: after the diagonal press over the table, before the descent) and at
the grasp, and where the input is held past the reach, are looked at and kept
(``UPDATE_SCREENSHOTS=1`` writes them to tests/browser/screenshots/). Each session takes
1.5-2 min on 2 cores under load (most of it the browser drawing each mouse move and key in
software WebGL); the printed phase times show where. Asserted: what the participant sees (the countdown, the outcome
sentence, the notice at the reach's edge, the handle above the target on the screen, nothing
with a condition word) and what lands in the store (three completed trials with outcome
success, every rating and answer as given).
"""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import expect

from app.robot.scene import grasp_position
from study.protocol import load_protocol
from study.server.live.texts import AT_REACH_LIMIT
from study.server.page_handle import HANDLE_PX
from study.server.participant_page import INSET_SIZE
from tests.browser.harness import FrameLog, RunningServer, start_server, wait_still, wait_until
from tests.browser.page import (
    AGREE,
    canvas_box,
    connect_page,
    hold,
    join,
    page_pixel,
    pixels_per_m,
    screenshot,
    settle_frames,
    wait_camera_still,
)
from tests.protocol_copies import PAPER_PROTOCOL, each_target_once

pytestmark = pytest.mark.browser

TIME_LIMIT_S = 90.0
PLANE_AT = 1.7 / 7
"""Centre of a plane square of the handle along each of its two axes, in arrow lengths (drei's
PivotControls); the square is 0.225 arrow lengths wide."""
CLOCK = re.compile(r"Time left: (\d+):(\d\d)")
KEYS = {0: ("w", "s"), 1: ("a", "d"), 2: ("r", "f")}
KEY_SPEED_M_S = 0.1
FOCUSED = """() => {
  const a = document.activeElement;
  if (!a || a === document.body) return {tag: "BODY", text: "", cls: "", value: ""};
  const numbered = [...document.querySelectorAll("button")].filter(
    (b) => b.offsetParent !== null && /^\\[?\\d\\]?$/.test(b.textContent.trim()));
  return {tag: a.tagName, text: a.textContent.trim(), cls: String(a.className || ""),
          value: a.value || "", row: numbered.indexOf(a)};
}"""
ABOUT_YOU = {
    "age_band": "25-34",
    "gender": "Prefer not to say",
    "handedness": "No, with my other hand",
    "robot_experience": "A little: I have seen or tried one once or twice",
}
KEEP = "Yes, you may keep and use my data"


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(
        tmp_path,
        time_limit_s=TIME_LIMIT_S,
        training_runs=1,
        asked_once=True,
        edit=each_target_once,
    )
    try:
        yield rs
    finally:
        rs.stop()


class Person:
    """One participant at the page: what they see (``seen``: every page text read), and where
    the things on the screen are (``live``: the server's session, whose positions the page
    draws)."""

    def __init__(self, rs: RunningServer, page: Any, code: str, shots: Path, name: str) -> None:
        self.rs, self.page, self.code, self.shots, self.name = rs, page, code, shots, name
        self.live = rs.server.session(code)
        self.seen: list[str] = []
        self.presses = 0
        self.t0 = time.monotonic()
        self.clock_at_start = 0

    def read(self) -> str:
        text = self.page.inner_text("body")
        self.seen.append(text)
        return text

    def mark(self, label: str) -> None:
        print(f"[{time.monotonic() - self.t0:6.1f} s] {self.name} {label}")

    def shot(self, label: str) -> None:
        self.mark(label)
        screenshot(self.page, self.shots, f"{self.name}-{label}", colors=256)

    # -- where things are -------------------------------------------------------------------
    @property
    def run(self) -> Any:
        return self.live.run

    def handle(self) -> np.ndarray:
        return np.asarray(self.live.page.handle.gizmo.position, float)

    def target(self) -> np.ndarray:
        return np.asarray(self.run.trial.user_target, float)

    def gripper(self) -> np.ndarray:
        return np.asarray(self.run.trial.poses().gripper, float)

    def goal(self) -> np.ndarray:
        scene = self.run.trial.scene
        return np.asarray(grasp_position(scene.spec.objects[scene.target_index]), float)

    def screen(self, point: np.ndarray, *, box: dict[str, float] | None = None) -> np.ndarray:
        """Where ``point`` is on the page (``box``: the canvas's, read once by a caller that
        places several points at one moment)."""
        return page_pixel(self.page, self.live.page.client.camera, point, box=box)

    def clock(self) -> int:
        m = CLOCK.search(self.read())
        assert m is not None, "no countdown on the trial screen"
        return int(m[1]) * 60 + int(m[2])

    # -- a run ------------------------------------------------------------------------------
    def start_run(self, press_start: Any) -> str:
        """From the ready screen into the run (``press_start`` presses Start); returns the
        target's name. Checks the countdown starts at the time limit."""
        self.page.get_by_role("button", name="Start").wait_for()
        self.mark("ready")
        settle_frames(self.page)
        press_start()
        self.page.get_by_role("button", name="Close the gripper (G)").wait_for()
        assert wait_until(lambda: self.run is not None and not self.run.over)
        assert wait_until(lambda: self.live.page.handle.gizmo is not None)
        self.mark("run started")
        wait_camera_still(self.live)
        self.clock_at_start = left = self.clock()
        assert TIME_LIMIT_S - 15 <= left <= TIME_LIMIT_S, left
        return self.run.trial.scene.target

    def wait_at_grasp(self, *, timeout: float = 20.0) -> float:
        """Watch the gripper come to rest at the grasp (the arm may have to help at the reach's
        edge) and return its distance from the grasp point. At rest, not within 1 cm: a target
        steered to within the keys' 8 mm on each axis can leave it 1-1.5 cm off, and waiting
        for 1 cm then sat out the whole ``timeout``."""
        wait_still(self.gripper, still_s=0.5, timeout=timeout)
        return float(np.linalg.norm(self.gripper() - self.goal()))

    def at_grasp(self, label: str) -> None:
        """What the participant sees at the grasp: the handle above the target on the screen,
        the target and gripper inside the view; a screenshot."""
        goal = self.goal()
        distance = self.wait_at_grasp()
        print(f"{self.name} {label}: gripper {1e3 * distance:.0f} mm from the grasp point")
        assert distance < 0.015, f"the gripper did not get to the grasp ({distance:.3f} m)"
        box = canvas_box(self.page)
        obj = self.screen(goal, box=box)
        origin = self.screen(self.handle(), box=box)
        # 12 cm above the target: 29 px in one CI run (a far target in this 1366 x 768
        # window); what matters is that it stands clear of the target, not on it
        above = obj[1] - origin[1]
        assert above > 20, f"the handle sits above the target on the screen ({above:.0f} px)"
        assert box["x"] < obj[0] < box["x"] + box["width"] and 0 < obj[1] < box["height"]
        assert self.clock() < self.clock_at_start, "the countdown runs"
        # The view from above shows the gripper's cross on the target: depth is read there.
        top = self.live.view.inset.camera
        w, h = INSET_SIZE
        cross, mark = (np.array(top.pixel(p, width=w, height=h)) for p in (self.gripper(), goal))
        assert 0 <= mark[0] < w and 0 <= mark[1] < h, "the target is in the view from above"
        assert np.linalg.norm(cross - mark) < 0.02 * h / top.extent_m, (cross, mark)
        reach = self.run.trial.scene.reach
        if not reach.contains(goal, tol=1e-6):
            # the robot's help took the gripper past the frame: the notice the participant
            # read at the frame spoke of what the handle and keys do, not of what the arm can
            assert not reach.contains(self.gripper(), tol=0.01), self.gripper()
            assert "handle" in AT_REACH_LIMIT and "keys" in AT_REACH_LIMIT
        self.shot(f"{label}-grasp")

    def finish_run(self, target: str, press_continue: Any) -> None:
        self.mark("grasp pressed")
        self.page.get_by_text("Run finished").wait_for(timeout=30_000)
        self.mark("run finished")
        body = self.read()
        assert f"You lifted the {target}." in body, body
        press_continue()

    def stuck(self, problem: str) -> None:
        """Fail with what the participant sees and what the session last recorded."""
        self.shot("stuck")
        events = [(e.kind, e.detail) for e in self.rs.store.events()][-6:]
        screen = self.live.session.screen()
        raise AssertionError(
            f"{problem}; run over: {self.run.over}, screen {screen.phase} (paused"
            f" {screen.paused}), page keys {self.live.page._keys_held}; last events {events};"
            f" page says: {self.read()[-600:]!r}"
        )

    # -- blinding ---------------------------------------------------------------------------
    def check_blinding(self, frames: FrameLog) -> None:
        words = set(self.rs.protocol.condition_words)
        words |= set(load_protocol(PAPER_PROTOCOL).condition_words)  # the copy drops some
        joined = "\n".join(self.seen).lower()
        raw = frames.raw_bytes()
        assert len(raw) > 10_000
        for word in sorted(words):
            assert word not in joined, f"condition word {word!r} on the page"
            assert word.encode() not in raw, f"condition word {word!r} on the page's websocket"
        assert self.rs.server.guard.violations == []


# -- the mouse ---------------------------------------------------------------------------------


def _mouse_path(page: Any, start: np.ndarray, end: np.ndarray, *, px: float = 25.0) -> None:
    """Move the (pressed) mouse from ``start`` to ``end`` ``px`` pixels at a time (each move
    waits for the page to take it: 0.1-0.3 s a move in software WebGL under load)."""
    n = max(2, int(np.ceil(np.linalg.norm(end - start) / px)))
    for k in range(1, n + 1):
        p = start + (end - start) * k / n
        page.mouse.move(float(p[0]), float(p[1]))
        page.wait_for_timeout(30)


def _grab(page: Any, at: np.ndarray) -> None:
    """Come to ``at`` from a little way off, as a hand does, and press."""
    page.mouse.move(float(at[0]) - 30, float(at[1]) + 20)
    page.wait_for_timeout(150)
    page.mouse.move(float(at[0]) - 4, float(at[1]) + 3)
    page.wait_for_timeout(150)
    page.mouse.move(float(at[0]), float(at[1]))
    page.wait_for_timeout(300)  # the handle lights up the part under the pointer
    page.mouse.down()
    page.wait_for_timeout(150)


def _arm_length_m(person: Person, *, box: dict[str, float] | None = None) -> float:
    """The handle's arrow length in metres at the handle (it is drawn HANDLE_PX long)."""
    cam = person.live.page.client.camera
    return HANDLE_PX / pixels_per_m(person.page, cam, person.handle(), box=box)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    t = float(np.clip((p - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-9), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * (b - a))))


def _plane_grip(person: Person) -> np.ndarray:
    """Where a person presses the table-plane square (world): the point of it farthest on the
    screen from the up arrow, which is drawn across the square's middle."""
    box = canvas_box(person.page)
    origin, length = person.handle(), _arm_length_m(person, box=box)
    base = person.screen(origin, box=box)
    tip = person.screen(origin + length * np.array([0, 0, 1.0]), box=box)
    half = 0.225 / 2 * 0.7  # inside the square's edges
    grid = np.linspace(PLANE_AT - half, PLANE_AT + half, 5)
    points = [origin + length * np.array([a, b, 0.0]) for a in grid for b in grid]
    return max(points, key=lambda w: _segment_distance(person.screen(w, box=box), base, tip))


def _drag_handle(
    person: Person,
    part: str,
    move: np.ndarray,
    *,
    midway: Any = None,
    release: bool = True,
) -> int:
    """Press the handle's ``part`` ("plane": the table-plane square; "up": the up arrow, near
    its tip) and drag it until the point grabbed has moved ``move`` (metres, world) on the
    screen: dragging a plane or an arrow moves the handle by what the cursor's ray moves in
    that plane or along that axis. ``midway()`` runs half way, the button held. A person
    who sees the wrong part move after the first few pixels lets go and presses again a little
    farther out; returns how many presses missed."""
    page = person.page
    axes = [0, 1] if part == "plane" else [2]
    for missed in range(3):
        origin = person.handle()
        box = canvas_box(page)
        length = _arm_length_m(person, box=box)
        if part == "plane":
            grabbed = _plane_grip(person) + 0.02 * missed * length * np.array([1.0, -1.0, 0])
        else:
            grabbed = origin + 0.75 * length * np.array([0.0, 0.0, 1.0])
        start = person.screen(grabbed, box=box)
        end = person.screen(grabbed + move, box=box)
        _grab(page, start)
        if not wait_until(lambda: person.live.page.dragging, timeout=5):
            page.mouse.up()
            raise AssertionError(f"pressing the handle's {part} at {start.round()} grabbed nothing")
        first = start + (end - start) * min(1.0, 30.0 / max(float(np.linalg.norm(end - start)), 1))
        _mouse_path(page, start, first)
        page.wait_for_timeout(300)
        moved = person.handle() - origin
        if np.abs(np.delete(moved, axes)).max() < 0.002:
            break
        print(f"{person.name}: pressing the {part} at {start.round()} moved {moved.round(3)}")
        _mouse_path(page, first, start)  # back where it was
        page.wait_for_timeout(300)
        page.mouse.up()
        assert wait_until(lambda: not person.live.page.dragging, timeout=5)
    else:
        raise AssertionError(f"three presses on the handle's {part} grabbed another part")
    half = start + 0.5 * (end - start)
    _mouse_path(page, first, half)
    if midway is not None:
        page.wait_for_timeout(200)
        midway()
    _mouse_path(page, half, end)
    page.wait_for_timeout(300)
    if release:
        page.mouse.up()
        assert wait_until(lambda: not person.live.page.dragging, timeout=5)
    return missed


def _reach_by_mouse(person: Person, label: str) -> None:
    """Over the target with the table-plane square (a long drag, then small corrections), then
    down with the up arrow, looking after each drag where the target point went."""
    goal = person.goal()
    reach = person.run.trial.scene.reach
    aim = np.clip(goal, reach.lo, reach.hi)  # where the handle can put the gripper
    beyond = not np.allclose(aim, goal, atol=1e-4)
    shot_mid = lambda: person.shot(f"{label}-mid-reach")  # noqa: E731
    for k in range(4):
        error = goal - person.target()
        error[2] = 0.0
        if np.linalg.norm((aim - person.target())[:2]) < 0.006:
            break
        if beyond and k == 0:
            # The target lies past the frame on the table: drag on to it; the notice says why
            # the gripper stops at the frame while the mouse is held.
            _drag_handle(person, "plane", error, midway=shot_mid, release=False)
            person.page.get_by_text(AT_REACH_LIMIT).first.wait_for(timeout=10_000)
            assert np.allclose(person.target()[:2], aim[:2], atol=0.01), person.target()
            person.shot(f"{label}-held-past-the-reach")
            person.page.mouse.up()
            assert wait_until(lambda: not person.live.page.dragging, timeout=5)
            notice = person.page.get_by_text(AT_REACH_LIMIT).first
            expect(notice).to_be_hidden(timeout=10_000)
            continue
        _drag_handle(person, "plane", error, midway=shot_mid if k == 0 else None)
        print(f"{person.name} {label}: plane drag {k}, target now {person.target().round(3)}")
    assert np.linalg.norm((aim - person.target())[:2]) < 0.012, (aim, person.target())
    for _ in range(4):
        dz = float(aim[2] - person.target()[2])
        if abs(dz) < 0.006:
            break
        _drag_handle(person, "up", np.array([0.0, 0.0, dz]))
        print(f"{person.name} {label}: arrow drag, target now {person.target().round(3)}")
    assert np.linalg.norm(aim - person.target()) < 0.015, (aim, person.target())


def _click_answers(page: Any, values: list[int]) -> None:
    """Click value ``values[k]`` on the ``k``-th rating row, then Continue."""
    cont = page.get_by_role("button", name="Continue")
    expect(cont).to_be_disabled()
    for k, value in enumerate(values):
        numbered = page.locator("button:visible").filter(has_text=re.compile(r"^\[?\d\]?$"))
        numbered.nth(7 * k + value - 1).click()
        expect(page.locator("button[data-study-chosen]")).to_have_count(k + 1)
    expect(cont).to_be_enabled()
    cont.click()


def _choose_by_mouse(page: Any, k: int, option: str) -> None:
    box = page.locator(".mantine-Select-input:visible").nth(k)
    box.click()
    page.get_by_role("option", name=option, exact=True).click()
    expect(box).to_have_value(option)


def test_a_whole_session_with_the_mouse_alone(
    study: RunningServer, wide: Any, screenshots: Path
) -> None:
    srv = study.server
    code = srv.enrol("P01")
    srv.act(code, "start")
    page = wide.new_page()
    frames = FrameLog().attach(page)
    t0 = time.monotonic()
    connect_page(page, study.url)
    join(page, code)  # typed: the one code the experimenter hands over
    me = Person(study, page, code, screenshots, "mouse")
    me.read()
    page.get_by_role("button", name=AGREE).click()

    # About you: four dropdowns clicked, the hours typed (a number cannot be clicked).
    page.get_by_text("How old are you?").wait_for()
    me.read()
    for k, option in enumerate(ABOUT_YOU.values()):
        _choose_by_mouse(page, k, option)
    field = page.locator(".mantine-TextInput-input:visible").first
    field.click()
    page.keyboard.type("4")
    page.get_by_text("Your answer: 4 hours per week").wait_for()
    page.get_by_role("button", name="Continue").click()

    ratings = [[5, 4, 5], [6, 6, 5], [4, 3, 4]]
    for n in range(3):
        target = me.start_run(lambda: page.get_by_role("button", name="Start").click())
        label = f"run{n + 1}"
        me.shot(f"{label}-start")
        _reach_by_mouse(me, label)
        me.at_grasp(label)
        page.get_by_role("button", name="Close the gripper (G)").click()
        me.finish_run(target, lambda: page.get_by_role("button", name="Continue").click())
        page.get_by_text("Your answer: none yet").first.wait_for()
        me.read()
        _click_answers(page, ratings[n])
        if n == 1:  # the attention check between the two tasks
            page.get_by_text("please choose Somewhat").wait_for()
            me.read()
            _choose_by_mouse(page, 0, "Somewhat")
            me.shot("attention")
            page.get_by_role("button", name="Continue").click()

    # Closing: the comment is optional and left empty; keep the data; the debrief; the end.
    page.get_by_text("anything else you would like to tell us").wait_for()
    me.read()
    _choose_by_mouse(page, 0, KEEP)
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="Finish").wait_for()
    me.read()
    page.get_by_role("button", name="Finish").click()
    page.get_by_text("You may close this page now.").wait_for()
    me.read()
    print(f"mouse session: {time.monotonic() - t0:.0f} s")
    _check_store(study, "P01", ratings, comment=None, hours=4.0)
    me.check_blinding(frames)


# -- the keys ----------------------------------------------------------------------------------


def _focus(page: Any, want: Any, *, presses: int = 40) -> dict[str, Any]:
    """Press Tab until the focused element satisfies ``want`` (a participant's eye on the
    focus ring); return what is focused. The focus moves while the browser handles the Tab
    (the press returns after that); only a focus seen not to have moved is read again later."""
    focused = page.evaluate(FOCUSED)
    for _ in range(presses):
        before = focused
        page.keyboard.press("Tab")
        focused = page.evaluate(FOCUSED)
        if focused == before:
            page.wait_for_timeout(80)
            focused = page.evaluate(FOCUSED)
        if want(focused):
            return focused
    raise AssertionError(f"Tab never reached the element wanted; last {focused}")


def _press_button(page: Any, label: str) -> None:
    """Tab to the button ``label`` and press Enter."""
    _focus(page, lambda f: f["tag"] == "BUTTON" and f["text"] == label)
    page.keyboard.press("Enter")


def _choose_by_keys(page: Any, k: int, option: str) -> None:
    """Tab to the ``k``-th dropdown on the screen, open it with the down arrow, go down to
    ``option`` and press Enter."""
    boxes = page.locator(".mantine-Select-input:visible")
    handle = boxes.nth(k).element_handle()
    _focus(page, lambda _f: page.evaluate("(e) => document.activeElement === e", handle))
    page.keyboard.press("ArrowDown")
    page.get_by_role("option").first.wait_for()
    for _ in range(12):
        current = page.locator("[data-combobox-selected]")
        if current.count() and current.first.inner_text().strip() == option:
            break
        page.keyboard.press("ArrowDown")
        page.wait_for_timeout(80)
    page.keyboard.press("Enter")
    expect(boxes.nth(k)).to_have_value(option)


def _rate_by_keys(page: Any, values: list[int]) -> None:
    """For each row, Tab to its button ``values[k]`` and press Enter; then Continue."""
    for k, value in enumerate(values):
        _focus(page, lambda f, k=k, v=value: f.get("row") == 7 * k + v - 1)
        page.keyboard.press("Enter")
        expect(page.locator("button[data-study-chosen]")).to_have_count(k + 1)
    _press_button(page, "Continue")


def _steer(person: Person, goal: np.ndarray, axes: tuple[int, ...], *, tol: float = 0.008):
    """Hold the keys (auto-repeat) until the target is within ``tol`` of ``goal`` on ``axes``,
    looking after each press where it went, as a person does: a held key moves the target at
    0.1 m/s for as long as the page saw it held, which on a slow machine is longer than the
    finger held it (the release waits behind a frame: 3-5 cm too far under load). So each
    press is as long as the last one's gain says, and after an overshoot the next is shorter,
    down to a tap (a press and release, at least 8 mm)."""
    gain = 1.0  # metres moved per metre meant, learnt from the presses so far
    still = 0
    for axis in axes:
        for _ in range(14):
            error = goal[axis] - float(person.target()[axis])
            if abs(error) < tol:
                break
            key = KEYS[axis][0 if error > 0 else 1]
            seconds = 0.9 * abs(error) / gain / KEY_SPEED_M_S
            before = float(person.target()[axis])
            if seconds < 0.15:
                person.page.keyboard.press(key)  # a tap
            else:
                hold(person.page, key, min(seconds, 3.0))
            wait_still(person.target, still_s=0.2, timeout=3)  # the release landed
            moved = abs(float(person.target()[axis]) - before)
            if seconds >= 0.15 and moved > 0:
                gain = float(np.clip(0.5 * gain + 0.5 * moved / (seconds * KEY_SPEED_M_S), 1, 4))
            person.presses += 1
            print(f"{person.name}: {key} {seconds:.2f} s, target {person.target().round(3)}")
            still = still + 1 if moved < 1e-4 else 0
            if still == 3:
                person.stuck(f"three presses of {key!r} did not move the target")


def _diagonal(person: Person, aim: np.ndarray) -> None:
    """Hold the away/back and the sideways key together (the target moves diagonally), let go
    of each when it has done about four fifths of its way; the last one pressed repeats."""
    error = aim - person.target()
    keys = [
        (KEYS[a][0 if error[a] > 0 else 1], 0.8 * abs(error[a]) / KEY_SPEED_M_S) for a in (0, 1)
    ]
    keys.sort(key=lambda k: k[1])
    page, t0 = person.page, time.monotonic()
    for key, _ in keys:
        page.keyboard.down(key)
    for key, seconds in keys:
        while time.monotonic() - t0 < seconds:
            page.wait_for_timeout(33)
            page.keyboard.down(keys[-1][0])  # auto-repeat of the key pressed last
        page.keyboard.up(key)
    person.presses += 1
    wait_still(person.target, still_s=0.2, timeout=3)
    print(
        f"{person.name}: {'+'.join(k for k, _ in keys)} together, target {person.target().round(3)}"
    )


def _reach_by_keys(person: Person, label: str) -> None:
    goal = person.goal()
    reach = person.run.trial.scene.reach
    aim = np.clip(goal, reach.lo, reach.hi)
    _diagonal(person, aim)
    person.shot(f"{label}-mid-reach")  # on the way, over the table, before the descent
    _steer(person, aim, (0, 1))
    if not np.allclose(aim, goal, atol=1e-4):
        # the box is past the frame: W held on, the notice says why the gripper stops
        page = person.page
        page.keyboard.down("w")
        page.get_by_text(AT_REACH_LIMIT).first.wait_for(timeout=10_000)
        person.shot(f"{label}-held-past-the-reach")
        hold(page, "w", 1.0)
        notice = page.get_by_text(AT_REACH_LIMIT).first
        assert wait_until(lambda: not notice.is_visible(), timeout=10)
    _steer(person, aim, (2,))
    assert np.abs(aim - person.target()).max() < 0.012, (aim, person.target())


def test_a_whole_session_with_the_keys_alone(
    study: RunningServer, wide: Any, screenshots: Path
) -> None:
    srv = study.server
    code = srv.enrol("P02")
    srv.act(code, "start")
    page = wide.new_page()
    frames = FrameLog().attach(page)
    t0 = time.monotonic()
    connect_page(page, study.url)
    page.get_by_text("Please type the join code").wait_for()
    _focus(page, lambda f: f["tag"] == "INPUT")
    page.keyboard.type(code.lower(), delay=40)
    page.keyboard.press("Enter")  # joins
    page.get_by_role("button", name=AGREE).wait_for()
    me = Person(study, page, code, screenshots, "keys")
    me.read()
    _press_button(page, AGREE)

    page.get_by_text("How old are you?").wait_for()
    for k, option in enumerate(ABOUT_YOU.values()):
        _choose_by_keys(page, k, option)
    _focus(page, lambda f: "TextInput" in f["cls"])
    page.keyboard.type("12")
    page.get_by_text("Your answer: 12 hours per week").wait_for()
    _press_button(page, "Continue")

    ratings = [[3, 4, 3], [7, 6, 7], [2, 2, 3]]
    for n in range(3):
        target = me.start_run(lambda: _press_button(page, "Start"))
        label = f"run{n + 1}"
        me.shot(f"{label}-start")
        _reach_by_keys(me, label)
        me.at_grasp(label)
        hold(page, "g", 0.2)
        me.finish_run(target, lambda: _press_button(page, "Continue"))
        page.get_by_text("Your answer: none yet").first.wait_for()
        me.read()
        _rate_by_keys(page, ratings[n])
        if n == 1:
            page.get_by_text("please choose Somewhat").wait_for()
            me.read()
            _choose_by_keys(page, 0, "Somewhat")
            _press_button(page, "Continue")

    page.get_by_text("anything else you would like to tell us").wait_for()
    me.read()
    _focus(page, lambda f: f["tag"] == "TEXTAREA")
    comment = "Steering with the keys was slow but exact. The second box was hard to see."
    page.keyboard.type(comment, delay=5)  # W, S, A, D, R, F and G type letters in the field
    page.get_by_text(f"{len(comment)} of 1000 characters.").wait_for()
    _choose_by_keys(page, 0, KEEP)
    _press_button(page, "Continue")
    _press_button(page, "Finish")
    page.get_by_text("You may close this page now.").wait_for()
    me.read()
    print(f"keys session: {time.monotonic() - t0:.0f} s")
    _check_store(study, "P02", ratings, comment=comment, hours=12.0)
    me.check_blinding(frames)


# -- the store ---------------------------------------------------------------------------------


def _check_store(
    rs: RunningServer,
    participant: str,
    ratings: list[list[int]],
    *,
    comment: str | None,
    hours: float,
) -> None:
    store = rs.store
    assert wait_until(lambda: store.session(participant).status == "completed")
    trials = store.trials(participant=participant)
    assert [(t.phase, t.status, t.outcome) for t in trials] == [
        ("training", "completed", "success"),
        ("task", "completed", "success"),
        ("task", "completed", "success"),
    ]
    assert sorted(t.difficulty for t in trials[1:]) == ["easy", "hard"]
    for t in trials:
        assert 0 < t.duration_s < TIME_LIMIT_S
    got = store.ratings(participant=participant)
    by_trial: list[list[int]] = []
    for phase in ("training", "task"):
        rows = [r for r in got if r.phase == phase]
        for k in range(0, len(rows), 3):
            by_trial.append([r.value for r in rows[k : k + 3]])
            assert [r.item for r in rows[k : k + 3]] == ["helpful", "matched", "teammate"]
    assert by_trial == ratings
    answers = {a.item: a for a in store.answers(participant=participant)}
    assert {k: answers[k].value for k in ABOUT_YOU} == ABOUT_YOU
    assert answers["game_hours"].number == hours
    assert answers["attention"].value == "Somewhat"
    assert answers["comment"].value == comment
    assert answers["keep_data"].value == KEEP
