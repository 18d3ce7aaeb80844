"""A hostile or broken participant client cannot hurt the server or the data.

A bare websocket client speaks viser's protocol to the participant server: it binds to the
session like a tab, clicks through consent, and then sends what no honest browser sends -
NaN and misshapen gizmo poses, answers off the 7-point scale, a Continue before every item is
answered, updates to properties that do not exist, and bytes that are not msgpack at all.
Each is rejected (with a notice to the client and an ``input_rejected`` event where it reaches
the study), nothing bad lands in the store, and the server keeps serving.
"""

from __future__ import annotations

import asyncio
import math
import time
from pathlib import Path
from typing import Any

from study.server.draw_rate import scene_hz
from tests.browser.harness import run_async, start_server, wait_until
from tests.support.raw_client import AGREE, RawClient

"""The paper protocol's consent button (``[consent] agree``)."""


def _kinds(store: Any) -> list[str]:
    return [e.kind for e in store.events()]


def test_malformed_client_messages_are_rejected_and_the_server_keeps_running(
    tmp_path: Path,
) -> None:
    rs = start_server(tmp_path, time_limit_s=3.0, training_runs=1)
    srv = rs.server
    try:
        code = srv.enrol("P01")
        srv.act(code, "start")
        live = srv.session(code)

        async def scenario() -> None:
            async with RawClient(srv.participant_port) as c:
                await c.join(code)
                await c.click(AGREE)
                await c.click("Start")
                gizmo = await c.wait_for(
                    lambda m: m.get("type") == "TransformControlsMessage" and m["name"] == "/handle"
                )
                owner = gizmo.get("owner", "")
                assert wait_until(lambda: live.participant_input is not None)
                good = live.participant_input.gizmo.target
                dropped = sum(srv.firewall.dropped.values())

                # NaN, infinite and huge poses, a pose of the wrong shape, a property that is not
                # a value, bytes that are not msgpack: refused at the door, target unchanged.
                for bad in ((math.nan, 0.0, 0.3), (0.5, math.inf, 0.3), (1e200, 0.0, 0.3), (0.5,)):
                    await c.pose(bad, owner=owner)
                await c.send(
                    "GuiUpdateMessage",
                    uuid=await c.button("Close the gripper (G)"),
                    updates={"x": 1},
                )
                await c.ws.send(b"\x00\x01 not msgpack")
                await asyncio.sleep(0.5)
                assert sum(srv.firewall.dropped.values()) == dropped + 6
                assert (
                    live.participant_input.gizmo.target is None
                    or (live.participant_input.gizmo.target == good).all()
                )
                # The page's drawing rate (study.server.draw_rate): anything but a whole number
                # 1..1000 is refused and changes nothing; a good one paces this tab's updates.
                fps = await c.wait_for(
                    lambda m: m.get("type") == "GuiTextMessage" and m["props"]["label"] == "fps"
                )
                page = live.page
                rejected = len(page.rejected)
                for value in ("0", "1001", "abc", "1e3", "12.5", "-4", "\u0661\u0662", "9" * 500):
                    await c.send("GuiUpdateMessage", uuid=fps["uuid"], updates={"value": value})
                await c.send("GuiUpdateMessage", uuid=fps["uuid"], updates={"value": "12"})
                assert wait_until(lambda: page.draw_hz == 12.0, timeout=5)
                assert len(page.rejected) == rejected + 8, list(page.rejected)[rejected:]
                assert scene_hz(page.draw_hz, render_hz=srv.render_hz) == 24.0

                # A valid pose still works afterwards; the control loop never stopped.
                await c.pose((0.5, 0.1, 0.35), owner=owner)
                assert wait_until(
                    lambda: (
                        live.run is not None
                        and abs(float(live.run.trial.user_target[1]) - 0.1) < 1e-9
                    ),
                    timeout=5,
                )
                assert live.control_loop is not None and live.control_loop.error is None

                # After the (3 s) practice run: a neutral sentence, then the items, where
                # off-scale answers are refused.
                await c.button("Continue")
                assert any(
                    m.get("type") == "GuiMarkdownMessage"
                    and "Time is up" in m["props"]["_markdown"]
                    for m in c.messages
                )
                await c.click("Continue")
                groups = []
                deadline = time.monotonic() + 20
                while len(groups) < 3 and time.monotonic() < deadline:
                    groups = [m for m in c.messages if m.get("type") == "GuiButtonGroupMessage"]
                    await asyncio.sleep(0.1)
                assert len(groups) == 3
                n_notices = c.notices()
                for value in ("9", "0", "abc", "-3", "4.5"):
                    await c.send(
                        "GuiUpdateMessage", uuid=groups[0]["uuid"], updates={"value": value}
                    )
                await c.click("Continue")  # before any answer: refused
                await asyncio.sleep(0.5)
                assert c.notices() >= n_notices + 6
                assert rs.store.ratings() == []
                for g in groups:
                    await c.send("GuiUpdateMessage", uuid=g["uuid"], updates={"value": "6"})
                await asyncio.sleep(0.3)
                await c.click("Continue")
                assert wait_until(lambda: len(rs.store.ratings()) == 3, timeout=5)
                assert {r.value for r in rs.store.ratings()} == {6}

        run_async(scenario())
        # The server still serves: a new client connects, joins and gets the page.
        assert wait_until(lambda: live.page is None, timeout=5)

        async def second() -> None:
            async with RawClient(srv.participant_port) as c:
                await c.join(code, then="Start")

        run_async(second())
        assert "input_rejected" in _kinds(rs.store)
        assert srv.guard.violations == []
    finally:
        rs.stop()
