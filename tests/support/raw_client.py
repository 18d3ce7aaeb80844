"""A websocket client that speaks viser's protocol by hand, as a browser tab would or as an
attacker could: connect with the page's subprotocol, send any message, read what comes back."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Iterable
from typing import Any

import msgspec
import viser
import websockets

from study.server.participant_page import ParticipantPage
from tests.browser.harness import decode_frame
from tests.browser.page import AGREE


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


async def bare_page(
    server: viser.ViserServer, *, words: Iterable[str], title: str = "Robot arm study"
) -> ParticipantPage:
    """The participant page of the one tab connected to ``server`` (a plain viser server, no
    study session behind it), once that tab is there."""
    for _ in range(100):
        if server.get_clients():
            break
        await asyncio.sleep(0.05)
    (client,) = server.get_clients().values()
    return ParticipantPage(client, title=title, words=words)
