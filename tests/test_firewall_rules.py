"""The participant port's inbound rules, message by message (no server needed)."""

from __future__ import annotations

import importlib
import inspect
import math
import threading
import time

import msgspec
import numpy as np
import pytest
import viser
import websockets.asyncio.server as ws_server
from viser.infra import _infra
from viser.infra._async_message_buffer import AsyncMessageBuffer
from viser.infra._messages import Message

from study.server import blinding_guard, firewall, viser_door
from study.server.firewall import MAX_MESSAGE_BYTES, Firewall, FirewallConfig
from study.server.firewall.rules import MAX_GUI_TEXT
from study.server.firewall.shares import MAX_ADDRESSES, AcceptGate, FairShares
from study.server.firewall.slots import Slots
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
    # a free-text answer of 2,000 characters passes; a GUI value past MAX_GUI_TEXT does not
    assert fw.screen(_raw("GuiUpdateMessage", uuid="a", updates={"value": "x" * 2000})) is None
    too_long = "x" * (MAX_GUI_TEXT + 1)
    assert fw.screen(_raw("GuiUpdateMessage", uuid="a", updates={"value": too_long})) is not None
    assert fw.screen(_raw("GuiUpdateMessage", uuid="a", updates={"value": [1, 2]})) is not None
    assert "share" in (fw.screen(_raw("ShareUrlRequest")) or "")
    assert "not accepted" in (fw.screen(_raw("FileTransferStartUpload", uuid="x")) or "")
    assert fw.screen(b"\x00 not msgpack") == "not a viser message"
    big = _pose([0.5, 0.0, 0.3], owner="x" * MAX_MESSAGE_BYTES)
    reason = fw.screen(big)
    assert reason is not None and "bytes" in reason and len(reason) < 100


def test_poses_far_away_zero_quaternions_and_degenerate_cameras_are_refused() -> None:
    """Each component within bounds, but 17 m from the origin; a zero rotation; a camera that
    looks at its own position (viser cannot turn it, and the tab used to get no join screen)."""
    fw = Firewall()
    assert "handle position" in (fw.screen(_pose([10.0, 10.0, 10.0])) or "")
    assert "farther than 3" in (fw.screen(_pose([2.9, 2.9, 2.9])) or "")
    assert fw.screen(_pose([1.8, 1.8, 1.8])) is not None  # 3.1 m
    assert fw.screen(_pose([1.0, 1.0, 1.0])) is None
    zero = _raw(
        "TransformControlsUpdateMessage", name="/handle", wxyz=[0.0] * 4, position=[0.5, 0, 0.3]
    )
    assert "unit quaternion" in (fw.screen(zero) or "")
    camera = {
        "wxyz": [1.0, 0.0, 0.0, 0.0],
        "position": [0.4, 0.0, 0.1],
        "look_at": [0.4, 0.0, 0.1],
        "up_direction": [0.0, 0.0, 1.0],
        "fov": 1.0,
        "near": 0.01,
        "far": 1000.0,
        "image_height": 720,
        "image_width": 1100,
    }
    assert "own position" in (fw.screen(_raw("ViewerCameraMessage", **camera)) or "")
    camera["wxyz"] = [0.0, 0.0, 0.0, 0.0]
    camera["position"] = [-1.0, 0.0, 1.0]
    assert "unit quaternion" in (fw.screen(_raw("ViewerCameraMessage", **camera)) or "")


def test_share_links_only_when_the_experimenter_asks() -> None:
    assert Firewall(FirewallConfig(allowed=None)).screen(_raw("ShareUrlRequest")) is not None
    assert (
        Firewall(FirewallConfig(allowed=None, allow_share=True)).screen(_raw("ShareUrlRequest"))
        is None
    )
    assert (
        Firewall(FirewallConfig(allowed=None)).screen(_raw("FileTransferStartUpload", uuid="x"))
        is None
    )


def test_refusals_are_counted_and_logged_once_per_reason(caplog) -> None:
    fw = Firewall()
    for _ in range(100):
        fw.refuse(fw.screen(_pose([math.inf, 0, 0])) or "")
    assert fw.dropped["TransformControlsUpdateMessage"] == 100
    assert len([r for r in caplog.records if "refused" in r.getMessage()]) == 1


def test_a_client_cannot_make_a_log_line_per_size_or_per_type_name(caplog) -> None:
    """Refusals are counted and logged by kind: a client choosing a new size or a new type
    name for each message still gets one line per kind (issue 22's log growth)."""
    fw = Firewall()
    names = [f"Made{k}UpMessage" for k in range(150)]
    names += ["RunJavascriptMessage", "FileTransferStartUpload"]
    for name in names:
        fw.refuse(fw.screen(msgspec.msgpack.encode({"type": name})) or "")
    for size in range(17_000, 17_200):
        fw.refuse(fw.screen(b"x" * size) or "")
    lines = [r.getMessage() for r in caplog.records if "refused" in r.getMessage()]
    assert len(lines) == 2, lines
    assert fw.dropped["an unknown type is not accepted here"] == 150  # counted by type
    assert fw.dropped["RunJavascriptMessage is not accepted here"] == 1


def test_far_poses_from_a_tab_that_holds_a_session_never_close_it() -> None:
    """A handle dragged along an axis seen nearly edge-on can go metres off; the poses are
    refused (the trial keeps the last good one) but the participant's tab stays open. The same
    poses from a connection without a session close it after ``max_refused``."""
    clock = _Clock()
    fw = Firewall(clock=clock)
    far = _pose([3.2, 0.0, 0.3])

    def send(bound: bool) -> int:
        sock = _Socket("10.0.0.2", b"x", clock=clock, period=0.0)
        fw.slots.admit(sock, "10.0.0.2", now=clock())

        async def go() -> int:
            await fw.screened_recv(sock)()
            fw.slots.get(sock).bound = bound
            for k in range(600):  # 20 s of a drag at 30 poses a second
                clock.now += 1 / 30
                try:
                    fw.screened_decode(far, msgspec.msgpack.decode)
                except firewall.ConnectionFlood:
                    return k
            return -1

        return run_async(go())

    assert send(bound=True) == -1
    assert 150 < send(bound=False) < 600


def _resolve(dotted: str) -> object:
    """The object a dotted name of :data:`viser_door.PRIVATE_REACHES` names (module, then
    attributes), or the class attribute for an instance attribute a class declares."""
    parts = dotted.split(" ")[0].split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for name in parts[k:]:
            obj = getattr(obj, name)
        return obj
    raise AssertionError(f"{dotted}: no module")


def test_viser_is_the_pinned_minor_version() -> None:
    """viser is pinned to the tested minor version; an upgrade means reading viser_door."""
    assert viser.__version__.startswith("1.1.")
    assert f"viser-v{viser.__version__}" == viser_door.SUBPROTOCOL


def test_the_viser_internals_the_door_reaches_are_where_it_expects() -> None:
    """Every private name study.server.viser_door uses exists where it expects it: the hooks
    with the signatures the wrappers forward, and on a live server its connections, a tab's
    message channel and an element's id."""
    hooks = {
        "viser._messages.Message.deserialize": (
            viser_door._ORIGINAL_DESERIALIZE,
            ["cls", "message"],
        ),
        "viser.infra._async_message_buffer.AsyncMessageBuffer.push": (
            viser_door._ORIGINAL_PUSH,
            ["self", "message"],
        ),
        "viser.infra._messages.Message.as_serializable_dict": (
            viser_door._ORIGINAL_SERIALIZE,
            ["self", "binary_buffers"],
        ),
    }
    assert set(hooks) <= set(viser_door.PRIVATE_REACHES)
    assert AsyncMessageBuffer.__module__ == "viser.infra._async_message_buffer"
    assert Message.__module__ == "viser.infra._messages"
    assert issubclass(viser_door.Message, Message)
    for name, (original, params) in hooks.items():
        assert list(inspect.signature(original).parameters) == params, name
    for name in (
        "viser._messages.Message.deserialize",
        "viser.infra._messages.Message._subclass_from_type_string",
        "viser._messages.RunJavascriptMessage",
    ):
        assert callable(_resolve(name)), name
    assert "websockets.asyncio.server.serve" in " ".join(viser_door.PRIVATE_REACHES)
    assert callable(ws_server.serve)
    assert viser_door.is_message_type("GuiUpdateMessage")
    assert any(c.__name__ == "RunJavascriptMessage" for c in viser_door.message_classes())
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        ws = server._websock_server
        assert isinstance(ws, _infra.WebsockServer)
        assert isinstance(ws._live_connections, dict)
        assert viser_door.event_loop(server) is ws._background_event_loop
        buffer = ws.get_message_buffer()
        assert buffer.persistent_messages is True
        assert buffer.event_loop is viser_door.event_loop(server)
        text = server.gui.add_text("t", initial_value="")
        assert isinstance(viser_door.element_uuid(text), str)
        assert hasattr(text._impl, "sync_cb")
        image = server.gui.add_image(np.zeros((2, 2, 3), np.uint8), format="jpeg")
        viser_door.set_image_bytes(image, b"jpeg")
        assert image._data == b"jpeg"
        assert viser_door.connection_of(server, 12345) is None
        assert isinstance(ws._server_thread, threading.Thread)
    finally:
        assert viser_door.stop_server(server)
    assert not ws._server_thread.is_alive()


def test_the_doors_hooks_reach_only_the_servers_that_use_them() -> None:
    """The blinding guard and the firewall go through viser_door's hooks: installed, each
    wraps viser's function (once per process), and acts only for the server it was installed
    on (``test_blinding_guard``: another server passes untouched)."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        guard = blinding_guard.install(server, words=("hard",))
        assert AsyncMessageBuffer.push is viser_door._watched_push
        assert Message.as_serializable_dict is viser_door._watched_serialize
        server.gui.add_markdown("a hard one")
        assert guard.checked >= 1 and guard.blocked == 1
        firewall.install(server, Firewall())
        assert viser_door._vm.Message.deserialize.__func__ is viser_door._screened_deserialize
    finally:
        firewall.uninstall(server)
        blinding_guard.uninstall(server)
        server.stop()


def test_the_console_may_send_long_text() -> None:
    """An experimenter's reason can be long; only the participant port bounds strings."""
    long_reason = _raw("GuiUpdateMessage", uuid="a", updates={"value": "r" * (MAX_GUI_TEXT + 1)})
    assert Firewall(FirewallConfig(allowed=None)).screen(long_reason) is None
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
    fw = Firewall(FirewallConfig(rate_per_s=200.0, burst=400.0), clock=clock)

    async def read(n_before: int, stall_s: float, backlog: int) -> None:
        await fw.screened_recv(_Socket("10.0.0.2", b"x", clock=clock, period=0.0))()
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


def test_unbound_addresses_share_the_budget_and_a_flood_waits_instead_of_dropping() -> None:
    """Two addresses without a session: one floods, one sends what a join screen sends. The
    quiet one never waits; the flood gets the rest of the budget, later, and loses nothing."""
    shares = FairShares(per_s=400.0)
    t, quiet_waits, flood_sent, flood_wait = 0.0, [], 0, 0.0
    while t < 5.0:
        if abs(t * 20 - round(t * 20)) < 1e-9:  # 20 messages a second
            quiet_waits.append(shares.delay("10.0.0.3", t))
        wait = shares.delay("10.0.0.2", t)  # a message as soon as the last was read
        flood_sent += 1
        flood_wait += wait
        t = round(t + max(wait, 1e-3), 9)
    assert max(quiet_waits) == 0.0
    assert 180 * 5 < flood_sent < 420 * 5  # its share (half, or all the quiet one leaves)
    assert shares.delayed >= flood_sent - 400  # the rest waited, none dropped


def test_a_bound_tab_never_waits_for_a_share(monkeypatch: pytest.MonkeyPatch) -> None:
    """The waits asked for, on the test's clock (a wait passes it on): none for the bound tab,
    about (30 - 10) / 10 s for 30 messages at once from a connection without a session."""
    clock = _Clock()
    fw = Firewall(FirewallConfig(shares_per_s=10.0), clock=clock)
    tab = _Socket("10.0.0.2", b"x", clock=clock, period=1 / 100)
    other = _Socket("10.0.0.2", b"x", clock=clock, period=1 / 100)
    fw.slots.admit(tab, "10.0.0.2", now=clock())
    fw.slots.admit(other, "10.0.0.2", now=clock())
    fw.slots.get(tab).bound = True
    read_tab, read_other = fw.screened_recv(tab), fw.screened_recv(other)
    waited: dict[object, float] = {tab: 0.0, other: 0.0}

    async def wait(connection: object, seconds: float) -> None:
        waited[connection] += seconds
        clock.now += seconds

    monkeypatch.setattr(firewall.port, "_unless_lost", wait)

    async def read(recv: object, n: int) -> None:
        for _ in range(n):
            await recv()  # type: ignore[operator]

    run_async(read(read_tab, 200))  # 200 messages at once, no wait
    assert waited[tab] == 0.0
    run_async(read(read_other, 30))  # 10 a second, burst 10: waits
    assert 1.5 < waited[other] < 2.5


def test_slots_are_shared_fairly_and_a_reserved_tab_always_gets_one() -> None:
    """Idle sockets from two addresses fill the port; a tab from a third address still gets in
    (the heaviest address's oldest idle socket makes room), bound tabs are never taken, and a
    tab that presents a rejoin token gets in even when nothing can be taken."""
    slots = Slots(max_total=8, max_per_address=8, greet_timeout_s=15.0, idle_timeout_s=600.0)
    holders = [object() for _ in range(8)]
    for k, conn in enumerate(holders):
        evict, problem = slots.admit(conn, "10.0.0.2" if k < 6 else "10.0.0.3", now=float(k))
        assert evict is None and problem is None
    newcomer = object()
    evict, problem = slots.admit(newcomer, "10.0.0.9", now=10.0)
    assert problem is None and evict is slots.get(holders[0])  # 10.0.0.2's oldest
    for conn in [*holders, newcomer]:
        if (slot := slots.get(conn)) is not None and not slot.closing:
            slot.bound = True  # every remaining socket now holds a session
    evict, problem = slots.admit(object(), "10.0.0.8", now=11.0)
    assert evict is None and problem is not None and "too many connections" in problem
    evict, problem = slots.admit(object(), "10.0.0.8", now=12.0, token="T" * 20)
    assert evict is None and problem is None
    slots.remove(holders[0])


def test_slots_time_out_without_a_first_message_or_idle_on_the_join_screen() -> None:
    slots = Slots(greet_timeout_s=15.0, idle_timeout_s=600.0)
    mute, waiting, bound = object(), object(), object()
    slots.admit(mute, "10.0.0.2", now=0.0)
    slots.admit(waiting, "10.0.0.3", now=0.0)
    slots.admit(bound, "10.0.0.4", now=0.0)
    slots.get(waiting).greeted = True
    slots.get(bound).greeted = slots.get(bound).bound = True
    assert slots.overdue(10.0) == []
    assert slots.overdue(16.0) == [slots.get(mute)]
    slots.get(waiting).last_seen = 300.0
    assert slots.overdue(899.0) == []
    assert slots.overdue(901.0) == [slots.get(waiting)]  # bound tabs never time out
    assert slots.timed_out == 2


def test_the_accept_gate_turns_a_reconnect_storm_away_but_lets_a_quiet_address_in() -> None:
    gate = AcceptGate(per_s=1.0, burst=12.0, total_per_s=40.0)
    t = 0.0
    storm = 0
    for k in range(4000):  # 8 addresses reconnecting 400 times a second for 10 s
        t = k / 400
        storm += gate.allow(f"10.0.0.{k % 8}", t)
    assert storm <= 8 * (12 + 10 * 1.0) + 1
    assert gate.allow("10.0.0.99", t)  # a quiet address: a reload still gets in
    assert sum(gate.allow("10.0.0.99", t) for _ in range(20)) == 11  # its own burst, no more


def test_new_addresses_by_the_thousand_cost_no_scan_each_and_stay_bounded() -> None:
    """An attacker rotating its source address: each new one used to make the gate look
    through every address it knew (0.5-2.3 ms a connect at 1,000-5,000 a second); now it
    looks at most once a second, and forgets the oldest half past ``MAX_ADDRESSES``."""
    gate, shares = AcceptGate(per_s=1.0, burst=12.0, total_per_s=40.0), FairShares()
    rate = 5000.0
    start = time.perf_counter()
    for k in range(40_000):  # 8 s of new addresses, none idle long enough to forget
        gate.allow(f"10.{k >> 16}.{(k >> 8) & 255}.{k & 255}", k / rate)
        shares.delay(f"10.{k >> 16}.{(k >> 8) & 255}.{k & 255}", k / rate)
    per_connect_us = (time.perf_counter() - start) / 40_000 * 1e6
    assert per_connect_us < 200, per_connect_us  # a scan each: 1,000-4,000 here
    for k in range(40_000, 110_000):
        gate.allow(f"10.{k >> 16}.{(k >> 8) & 255}.{k & 255}", k / rate)
    assert len(gate._buckets) <= MAX_ADDRESSES
    assert gate.allow("10.200.0.1", 110_000 / rate)  # a new honest address still gets in


def test_a_text_frame_is_refused_before_viser_reads_it() -> None:
    fw = Firewall()
    recv = fw.screened_recv(_Socket("10.0.0.2", "hello", clock=_Clock(), period=0.0))
    with pytest.raises(firewall.ConnectionFlood) as closed:
        run_async(recv())
    assert closed.value.code == 1003 and fw.dropped["text frame"] == 1
