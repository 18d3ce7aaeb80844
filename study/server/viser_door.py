"""viser behind one door: every reach into viser's private parts goes through this module.

viser has no public hook on the messages a browser sends or on those it sends back, builds and
starts its websocket server inside its constructor, and keeps client connections, element
ids and the JavaScript channel private. The study server needs all of them: the firewall
(:mod:`study.server.firewall`) screens what comes in, the blinding guard
(:mod:`study.server.blinding_guard`) what goes out, the participant page runs its own script.
They are written as policy over the small public API here; an upgrade of viser means reading
this file (and the pin and hook tests, ``tests/test_firewall_rules.py``, which check every name in
:data:`PRIVATE_REACHES`). viser is pinned to the tested minor version in ``pyproject.toml``.

* Incoming (:func:`screen_incoming`): viser decodes every websocket message a browser sends
  with ``Message.deserialize`` on the server's event loop; the classmethod is wrapped once per
  process, and a message on the loop of a screened server goes to that server's screen with
  the original decoder (what the screen returns is dispatched; servers without one pass).
* Outgoing (:func:`watch_outgoing`): every message a server queues passes through an
  ``AsyncMessageBuffer`` (the broadcast buffer or one per client), and viser's sender calls
  ``Message.as_serializable_dict`` for each message just before encoding it; both are wrapped
  once per process, and on the loop of a watched server its :class:`OutgoingWatch` may drop a
  queued message or rewrite the outgoing dict.
* Serving (:func:`start_server`): viser starts serving before its constructor returns, so the
  websocket server's handler and options can only be set by swapping websockets' ``serve``
  while the constructor runs.
* A tab (:func:`connection_of`, :func:`run_javascript`), an element (:func:`element_uuid`,
  :func:`stop_echo`, :func:`set_image_bytes`) and viser's message types (:class:`Message`,
  :func:`is_message_type`, :func:`message_classes`).
* The page side: viser's browser client exposes itself, for its own end-to-end tests, as
  :data:`CLIENT_GLOBAL` (``.sendMessage``, ``.cameraControl``, ``.scene``); the page scripts
  name it through that constant (``tests/browser`` fails loudly if it moves).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import functools
import inspect
import threading
from collections.abc import Callable, Iterator
from typing import Any, Protocol

import viser
import websockets.asyncio.server as ws_server
from viser import _messages as _vm
from viser.infra._async_message_buffer import AsyncMessageBuffer
from viser.infra._messages import Message as _WireMessage

Message = _vm.Message
"""viser's message base class (a stand-in message, e.g. a refused one, derives from it)."""

SUBPROTOCOL = f"viser-v{viser.__version__}"
"""The websocket subprotocol viser's client offers: only a client of this version speaks it."""

CLIENT_GLOBAL = "window.__viserMutable"
"""The JavaScript name of viser's browser client (its message channel, camera and scene)."""

PRIVATE_REACHES: tuple[str, ...] = (
    "viser._messages.Message.deserialize",
    "viser.infra._messages.Message.as_serializable_dict",
    "viser.infra._messages.Message._subclass_from_type_string",
    "viser.infra._async_message_buffer.AsyncMessageBuffer.push",
    "viser.infra._async_message_buffer.AsyncMessageBuffer.persistent_messages",
    "viser.infra._async_message_buffer.AsyncMessageBuffer.event_loop",
    "viser.ViserServer._websock_server._live_connections",
    "viser.ViserServer._websock_server._server_thread",
    "viser.ClientHandle._websock_connection.queue_message",
    "viser._messages.RunJavascriptMessage",
    "viser._gui_handles._GuiInputHandle._impl.uuid",
    "viser._gui_handles._GuiInputHandle._impl.sync_cb",
    "viser.GuiImageHandle._data",
    "websockets.asyncio.server.serve (swapped while viser's constructor runs)",
    "window.__viserMutable (the browser client)",
)
"""Every private name of viser (and websockets) this module uses; the hook tests check each."""

Handler = Callable[[Any], Any]
ServeAdapter = Callable[[Handler, dict[str, Any]], tuple[Handler, dict[str, Any]]]
"""``(handler, serve keyword options) -> (handler, options)`` for viser's websocket server."""
Decode = Callable[[bytes], Any]
IncomingScreen = Callable[[bytes, Decode], Any]
"""``screen(raw, decode) -> message``: decode ``raw`` (or return a stand-in message)."""


class OutgoingWatch(Protocol):
    """What one watched server's outgoing messages pass through."""

    def on_queue(self, message: Any, *, own_echo: bool) -> bool:
        """A message being queued; False drops it. ``own_echo``: viser's echo of a value a tab
        typed, queued on that tab's own connection, which never sends it."""
        ...

    def on_serialize(self, out: dict[str, Any], *, message_type: str) -> dict[str, Any]:
        """The dict a message is about to be encoded from; the dict to encode instead."""
        ...


_LOCK = threading.Lock()
_SCREENS: dict[int, IncomingScreen] = {}
_WATCHES: dict[int, OutgoingWatch] = {}
_ORIGINAL_DESERIALIZE = _vm.Message.deserialize.__func__  # type: ignore[attr-defined]
_ORIGINAL_PUSH = AsyncMessageBuffer.push
_ORIGINAL_SERIALIZE = _WireMessage.as_serializable_dict


def _running_loop_id() -> int | None:
    try:
        return id(asyncio.get_running_loop())
    except RuntimeError:
        return None


# -- incoming ----------------------------------------------------------------------------------
def _screened_deserialize(cls: type[Any], message: bytes) -> Any:
    loop = _running_loop_id()
    screen = None if loop is None else _SCREENS.get(loop)
    if screen is None:
        return _ORIGINAL_DESERIALIZE(cls, message)
    return screen(message, functools.partial(_ORIGINAL_DESERIALIZE, cls))


def screen_incoming(server: viser.ViserServer, screen: IncomingScreen) -> None:
    """Send every message ``server`` receives from now on through ``screen`` before viser
    dispatches it (``screen`` runs on the server's event loop)."""
    with _LOCK:
        if getattr(_vm.Message.deserialize, "__func__", None) is not _screened_deserialize:
            _vm.Message.deserialize = classmethod(_screened_deserialize)  # type: ignore[method-assign,assignment]
        _SCREENS[id(server.get_event_loop())] = screen


def unscreen_incoming(server: viser.ViserServer) -> IncomingScreen | None:
    """Stop screening ``server``'s messages; returns the screen it had (``None``: none)."""
    with _LOCK:
        return _SCREENS.pop(id(server.get_event_loop()), None)


# -- outgoing ----------------------------------------------------------------------------------
def _is_own_echo(buffer: AsyncMessageBuffer, message: Any) -> bool:
    """``message`` is viser's echo of a value a tab typed, queued on that same tab's own
    connection, which skips it: a per-client buffer (not persistent) is read by one client
    only, the one ``excluded_self_client`` names. It will never be sent to anyone."""
    return (
        not buffer.persistent_messages
        and getattr(message, "excluded_self_client", None) is not None
        and type(message).__name__ == "GuiUpdateMessage"
    )


def _watched_push(self: AsyncMessageBuffer, message: Any) -> None:
    watch = _WATCHES.get(id(self.event_loop))
    if watch is not None and not watch.on_queue(message, own_echo=_is_own_echo(self, message)):
        return
    _ORIGINAL_PUSH(self, message)


def _watched_serialize(self: Any, binary_buffers: Any = None) -> dict[str, Any]:
    out = _ORIGINAL_SERIALIZE(self, binary_buffers)
    loop = _running_loop_id()
    watch = None if loop is None else _WATCHES.get(loop)
    if watch is None:
        return out
    return watch.on_serialize(out, message_type=type(self).__name__)


def watch_outgoing(server: viser.ViserServer, watch: OutgoingWatch) -> None:
    """Pass every message ``server`` queues and serialises from now on through ``watch``."""
    with _LOCK:
        if AsyncMessageBuffer.push is not _watched_push:
            AsyncMessageBuffer.push = _watched_push  # type: ignore[method-assign]
        if _WireMessage.as_serializable_dict is not _watched_serialize:
            _WireMessage.as_serializable_dict = _watched_serialize  # type: ignore[method-assign]
        _WATCHES[id(server.get_event_loop())] = watch


def unwatch_outgoing(server: viser.ViserServer) -> None:
    """Stop watching ``server``'s outgoing messages (call when it stops)."""
    with _LOCK:
        _WATCHES.pop(id(server.get_event_loop()), None)


# -- serving -----------------------------------------------------------------------------------
@contextlib.contextmanager
def _serve_adapted(adapt: ServeAdapter) -> Iterator[None]:
    original = ws_server.serve

    def serve(handler: Handler, *args: Any, **kwargs: Any) -> Any:
        handler, kwargs = adapt(handler, kwargs)
        return original(handler, *args, **kwargs)

    with _LOCK:
        ws_server.serve = serve  # type: ignore[assignment,misc]
    try:
        yield
    finally:
        with _LOCK:
            ws_server.serve = original  # type: ignore[misc]


def start_server(
    *, host: str, port: int, verbose: bool, adapt_serve: ServeAdapter | None = None
) -> viser.ViserServer:
    """A started ``ViserServer``; with ``adapt_serve``, its websocket server runs with the
    connection handler and ``websockets`` options ``adapt_serve`` makes of viser's."""
    if adapt_serve is None:
        return viser.ViserServer(host=host, port=port, verbose=verbose)
    with _serve_adapted(adapt_serve):
        return viser.ViserServer(host=host, port=port, verbose=verbose)


STOP_WAIT_S = 10.0
"""How long :func:`stop_server` waits for viser's server thread to end."""


def stop_server(server: viser.ViserServer) -> bool:
    """Stop ``server`` and wait (up to :data:`STOP_WAIT_S`) until its thread has ended, port
    closed; returns whether it has. ``ViserServer.stop`` waits 1 s: on a loaded machine the
    thread ended later and printed viser's "Server stopped" into whatever ran next (a CLI's
    one-line JSON output read two lines in a test)."""
    server.stop()
    thread = server._websock_server._server_thread
    if thread is not None and thread is not threading.current_thread():
        thread.join(STOP_WAIT_S)
        return not thread.is_alive()
    return True


def event_loop(server: viser.ViserServer) -> asyncio.AbstractEventLoop:
    """The event loop ``server`` serves and runs its message handlers on."""
    return server.get_event_loop()


# -- tabs and elements -------------------------------------------------------------------------
def connection_of(server: viser.ViserServer, client_id: int) -> Any | None:
    """The websockets connection of tab ``client_id`` (``None`` once it is gone)."""
    return server._websock_server._live_connections.get(client_id)


def run_javascript(client: viser.ClientHandle, source: str) -> None:
    """Queue ``source`` (JavaScript) to run once in ``client``'s tab."""
    client._websock_connection.queue_message(_vm.RunJavascriptMessage(source=source))


def element_uuid(handle: Any) -> str:
    """The id a GUI element's messages carry (a page script sends values to it by this id)."""
    return str(handle._impl.uuid)


def stop_echo(handle: Any) -> None:
    """Send the values a tab gives GUI element ``handle`` to no other tab (viser would queue
    each to "the other clients", building the message even when there are none)."""
    handle._impl.sync_cb = None


def set_image_bytes(handle: viser.GuiImageHandle, data: bytes) -> None:
    """Show ``data`` (already encoded in the handle's format) in image element ``handle``;
    viser would re-encode an array."""
    handle._data = data  # type: ignore[attr-defined]


# -- message types -----------------------------------------------------------------------------
def is_message_type(name: str) -> bool:
    """Whether ``name`` is the type of one of viser's messages."""
    return name in _vm.Message._subclass_from_type_string()


def message_classes() -> tuple[type, ...]:
    """viser's message classes (dataclasses: their field types declare what they carry)."""
    return tuple(
        cls for cls in vars(_vm).values() if inspect.isclass(cls) and dataclasses.is_dataclass(cls)
    )


__all__ = [
    "CLIENT_GLOBAL",
    "PRIVATE_REACHES",
    "SUBPROTOCOL",
    "IncomingScreen",
    "Message",
    "OutgoingWatch",
    "ServeAdapter",
    "connection_of",
    "element_uuid",
    "event_loop",
    "is_message_type",
    "message_classes",
    "run_javascript",
    "screen_incoming",
    "set_image_bytes",
    "start_server",
    "stop_echo",
    "unscreen_incoming",
    "unwatch_outgoing",
    "watch_outgoing",
]
