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
import contextlib
import math
import time
from pathlib import Path
from typing import Any

import msgspec
import viser
import websockets

from tests.browser.harness import decode_frame, run_async, start_server, wait_until

AGREE = "I have read this and agree to take part"
"""The paper protocol's consent button (``[consent] agree``)."""


class RawClient:
    """A minimal viser client: collects decoded messages, sends msgpack messages."""

    def __init__(self, port: int, *, headers: dict[str, str] | None = None) -> None:
        self.port = port
        self.headers = headers
        self.messages: list[dict[str, Any]] = []
        self.closed = False

    async def __aenter__(self) -> RawClient:
        self.ws = await websockets.connect(
            f"ws://127.0.0.1:{self.port}",
            subprotocols=[f"viser-v{viser.__version__}"],
            additional_headers=self.headers,
        )
        self._reader = asyncio.create_task(self._read())
        await self.send(
            "ViewerCameraMessage",
            wxyz=(1.0, 0.0, 0.0, 0.0),
            position=(-1.0, 0.0, 1.0),
            fov=1.0,
            near=0.01,
            far=100.0,
            image_height=600,
            image_width=800,
            look_at=(0.45, 0.0, 0.15),
            up_direction=(0.0, 0.0, 1.0),
        )
        return self

    async def __aexit__(self, *exc: object) -> None:
        self._reader.cancel()
        with contextlib.suppress(Exception):  # the server may have closed it already
            await self.ws.close()

    async def _read(self) -> None:
        try:
            async for frame in self.ws:
                self.messages.extend(decode_frame(frame))
        except websockets.ConnectionClosed:
            pass
        self.closed = True

    async def send(self, type_: str, **fields: Any) -> None:
        await self.ws.send(msgspec.msgpack.encode({"type": type_, **fields}))

    async def wait_for(self, pred: Any, timeout: float = 20.0) -> dict[str, Any]:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for m in reversed(self.messages):
                if pred(m):
                    return m
            await asyncio.sleep(0.05)
        raise AssertionError("expected message never arrived")

    async def button(self, label: str) -> str:
        m = await self.wait_for(
            lambda m: m.get("type") == "GuiButtonMessage" and m["props"]["label"] == label
        )
        return str(m["uuid"])

    async def click(self, label: str) -> None:
        await self.send("GuiUpdateMessage", uuid=await self.button(label), updates={"value": True})

    async def type_code(self, code: str) -> None:
        """Type ``code`` into the join screen's text field and press Join."""
        text = await self.wait_for(
            lambda m: m.get("type") == "GuiTextMessage" and m["props"]["label"] == "Join code"
        )
        await self.send("GuiUpdateMessage", uuid=text["uuid"], updates={"value": code})
        await asyncio.sleep(0.1)
        await self.click("Join")

    async def join(self, code: str, *, then: str = AGREE) -> None:
        """Join the session with ``code`` and wait for the button ``then``."""
        await self.type_code(code)
        await self.button(then)

    async def pose(self, position: Any, *, owner: str = "") -> None:
        await self.send(
            "TransformControlsUpdateMessage",
            name="/handle",
            wxyz=(1.0, 0.0, 0.0, 0.0),
            position=position,
            owner=owner,
        )

    def notices(self) -> int:
        return sum(
            1
            for m in self.messages
            if m.get("type") == "NotificationShowMessage" and "ignored" in str(m).lower()
        )


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
