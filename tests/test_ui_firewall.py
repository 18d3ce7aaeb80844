"""The participant port's inbound rules, message by message (no server needed)."""

from __future__ import annotations

import asyncio
import inspect
import math

import msgspec
import viser
from viser.infra import _infra
from viser.infra._async_message_buffer import AsyncMessageBuffer
from viser.infra._messages import Message

from study.server import blinding
from study.server.firewall import MAX_MESSAGE_BYTES, Firewall


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
