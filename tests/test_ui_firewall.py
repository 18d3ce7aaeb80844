"""The participant port's inbound rules, message by message (no server needed)."""

from __future__ import annotations

import asyncio
import inspect
import math

import msgspec
import pytest
import viser
from viser.infra import _infra
from viser.infra._async_message_buffer import AsyncMessageBuffer
from viser.infra._messages import Message

from study.server import blinding, firewall
from study.server.firewall import BUDGET, MAX_MESSAGE_BYTES, Firewall
from tests.browser.harness import run_async


def _raw(kind: str, **fields: object) -> bytes:
    return msgspec.msgpack.encode({"type": kind, **fields})


def _pose(position: object, **extra: object) -> bytes:
    return _raw(
        "TransformControlsUpdateMessage",
        name="/handle",
        wxyz=[1.0, 0.0, 0.0, 0.0],
        position=position,
        **extra,
    )


def test_what_a_participant_page_sends_passes() -> None:
    fw = Firewall()
    assert fw.screen(_pose([0.5, 0.0, 0.3], owner="")) is None
    assert fw.screen(_raw("GuiUpdateMessage", uuid="abc", updates={"value": "3"})) is None
    assert fw.screen(_raw("GuiUpdateMessage", uuid="abc", updates={"value": True})) is None
    camera = {
        "wxyz": [1.0, 0.0, 0.0, 0.0],
        "position": [-1.0, 0.0, 1.0],
        "look_at": [0.4, 0.0, 0.1],
        "up_direction": [0.0, 0.0, 1.0],
        "fov": 1.0,
        "near": 0.01,
        "far": 1000.0,
        "image_height": 720,
        "image_width": 1100,
    }
    assert fw.screen(_raw("ViewerCameraMessage", **camera)) is None


def test_bad_values_sizes_and_types_are_refused_with_a_short_reason() -> None:
    fw = Firewall()
    for position in ([math.nan, 0, 0], [1e200, 0, 0], [10.5, 0, 0], [0.5, 0.0], "abc"):
        reason = fw.screen(_pose(position))
        assert reason is not None and "handle position" in reason
    assert "value" in (fw.screen(_raw("GuiUpdateMessage", uuid="a", updates={"label": "x"})) or "")
    assert fw.screen(_raw("GuiUpdateMessage", uuid="a", updates={"value": "x" * 300})) is not None
    assert fw.screen(_raw("GuiUpdateMessage", uuid="a", updates={"value": [1, 2]})) is not None
    assert "share" in (fw.screen(_raw("ShareUrlRequest")) or "")
    assert "not accepted" in (fw.screen(_raw("FileTransferStartUpload", uuid="x")) or "")
    assert fw.screen(b"\x00 not msgpack") == "not a viser message"
    big = _pose([0.5, 0.0, 0.3], owner="x" * MAX_MESSAGE_BYTES)
    reason = fw.screen(big)
    assert reason is not None and "bytes" in reason and len(reason) < 100


def test_share_links_only_when_the_experimenter_asks() -> None:
    assert Firewall(allowed=None).screen(_raw("ShareUrlRequest")) is not None
    assert Firewall(allowed=None, allow_share=True).screen(_raw("ShareUrlRequest")) is None
    assert Firewall(allowed=None).screen(_raw("FileTransferStartUpload", uuid="x")) is None


def test_refusals_are_counted_and_logged_once_per_reason(caplog) -> None:
    fw = Firewall()
    for _ in range(100):
        fw.refuse(fw.screen(_pose([math.inf, 0, 0])) or "")
    assert fw.dropped["TransformControlsUpdateMessage"] == 100
    assert len([r for r in caplog.records if "refused" in r.getMessage()]) == 1


def test_the_viser_internals_the_firewall_relies_on_are_where_it_expects() -> None:
    """viser is pinned to the tested minor version; this fails loudly if a hook moved."""
    assert viser.__version__.startswith("1.1.")
    assert callable(viser._messages.Message.deserialize)


def test_the_viser_internals_the_blinding_guard_patches_are_where_it_expects() -> None:
    """Each hook of study.server.blinding.PATCHED_HOOKS exists with the signature the wrapper
    forwards, and the server keeps its event loop where install() reads it."""
    hooks = {
        "viser.infra._async_message_buffer.AsyncMessageBuffer.push": (
            blinding._ORIGINAL_PUSH,
            ["self", "message"],
        ),
        "viser.infra._messages.Message.as_serializable_dict": (
            blinding._ORIGINAL_SERIALIZE,
            ["self", "binary_buffers"],
        ),
    }
    assert set(hooks) == set(blinding.PATCHED_HOOKS)
    assert AsyncMessageBuffer.__module__ == "viser.infra._async_message_buffer"
    assert Message.__module__ == "viser.infra._messages"
    for name, (original, params) in hooks.items():
        assert list(inspect.signature(original).parameters) == params, name
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        loop = server._websock_server._background_event_loop
        assert isinstance(loop, asyncio.AbstractEventLoop)
        guard = blinding.install(server, words=("hard",))
        assert AsyncMessageBuffer.push is blinding._guarded_push
        assert Message.as_serializable_dict is blinding._guarded_serialize
        server.gui.add_markdown("a hard one")
        assert guard.checked >= 1 and guard.blocked == 1
    finally:
        blinding.uninstall(server)
        server.stop()
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        ws = server._websock_server
        assert isinstance(ws, _infra.WebsockServer)
        assert isinstance(ws._live_connections, dict)
        assert ws._background_event_loop is not None
    finally:
        server.stop()


def test_the_console_may_send_long_text() -> None:
    """An experimenter's reason can be long; only the participant port bounds strings."""
    long_reason = _raw("GuiUpdateMessage", uuid="a", updates={"value": "r" * 500})
    assert Firewall(allowed=None).screen(long_reason) is None
    assert Firewall().screen(long_reason) is not None


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


class _Socket:
    """Stands in for a websocket connection from one address: each read is a frame that
    arrived ``period`` seconds after the last (on ``clock``)."""

    def __init__(self, address: str, frame: bytes | str, *, clock: _Clock, period: float) -> None:
        self.remote_address = (address, 40000)
        self.frame, self.clock, self.period = frame, clock, period
        self.reads = 0

    async def recv(self) -> bytes | str:
        self.clock.now += self.period
        self.reads += 1
        return self.frame


def test_a_backlog_after_a_stall_is_not_a_flood() -> None:
    """A page at 180 messages a second whose server stalled 5 s has 900 queued messages, read
    at once; it keeps its connection. A client that sends 5,000 at once does not."""
    clock = _Clock()
    fw = Firewall(rate_per_s=200.0, burst=400.0, clock=clock)

    async def read(n_before: int, stall_s: float, backlog: int) -> None:
        for _ in range(n_before):
            clock.now += 1 / 180
            fw.admit()
        clock.now += stall_s
        for _ in range(backlog):
            fw.admit()

    run_async(read(500, 5.0, 900))
    assert fw.closed_connections == 0
    with pytest.raises(firewall.ConnectionFlood):
        run_async(read(10, 0.0, 5000))


def test_the_server_wide_budget_drops_the_excess_and_closes_the_heaviest_address() -> None:
    clock = _Clock()
    fw = Firewall(budget_per_s=1000.0, budget_burst=2000.0, evict_after_s=2, clock=clock)
    frame = _raw("NoSuchThing")
    page = _Socket("10.0.0.3", frame, clock=clock, period=0.01)
    flood = _Socket("10.0.0.2", frame, clock=clock, period=1 / 500)
    read_page, read_flood = fw.screened_recv(page), fw.screened_recv(flood)

    async def for_one_second(recv: object) -> int:
        """How many messages got through in one second of reading."""
        passed, end = 0, clock.now + 1.0
        while clock.now < end:
            await recv()  # type: ignore[operator]
            passed += 1
        return passed

    async def attack() -> tuple[int, int]:
        calm = await for_one_second(read_flood)  # 500 a second: within budget
        assert fw.dropped[BUDGET] == 0
        flood.period = 1 / 8000
        over = await for_one_second(read_flood)
        await read_page()
        with pytest.raises(firewall.ConnectionFlood):
            await for_one_second(read_flood)  # a second second over budget: closed
        return calm, over

    calm, over = run_async(attack())
    assert abs(calm - 500) <= 1 and fw.dropped[BUDGET] > 4000
    assert 2000 < over < 3200  # the unspent burst, then the budget's rate
    assert fw.closed_connections == 1
    run_async(read_page())  # the other address is still served


def test_a_text_frame_is_refused_before_viser_reads_it() -> None:
    fw = Firewall()
    recv = fw.screened_recv(_Socket("10.0.0.2", "hello", clock=_Clock(), period=0.0))
    with pytest.raises(firewall.ConnectionFlood) as closed:
        run_async(recv())
    assert closed.value.code == 1003 and fw.dropped["text frame"] == 1
