"""Inbound firewall for a viser server: what a browser may send, and how much.

viser decodes every websocket message a browser sends with ``Message.deserialize`` on the
server's event loop and dispatches it to whatever handler is registered for its type -- among
them ``ShareUrlRequest``, which opens a public tunnel. A :class:`Firewall` stands in front of
that, in parts:

* ``rules``: what one message may carry (types, sizes, values);
* ``limits``: how much one connection may send;
* ``shares``: fair shares of the server's time for connections that hold no session (messages
  and new connections, per address);
* ``slots``: who holds the port's connection slots, timeouts, and who gets one next;
* ``notes``: log lines a client can cause, rate-limited;
* ``policy``: the :class:`Firewall` itself -- the door checks at the handshake, and the limits
  and rules applied to every frame and message;
* ``hooks``: where it hooks into viser and websockets (:func:`hardened_serve`, :func:`install`).
"""

from study.server.firewall.hooks import hardened_serve, install, remote_host, uninstall
from study.server.firewall.port import REJOIN_COOKIE, Firewall
from study.server.firewall.rules import (
    LOOPBACK_NAMES,
    MAX_MESSAGE_BYTES,
    MAX_POSITION_M,
    MAX_STRING,
    PARTICIPANT_TYPES,
    SHARE_TYPES,
    ConnectionFlood,
    Dropped,
    RefusedMessage,
    check_values,
)

__all__ = [
    "LOOPBACK_NAMES",
    "MAX_MESSAGE_BYTES",
    "MAX_POSITION_M",
    "MAX_STRING",
    "PARTICIPANT_TYPES",
    "REJOIN_COOKIE",
    "SHARE_TYPES",
    "ConnectionFlood",
    "Dropped",
    "Firewall",
    "RefusedMessage",
    "check_values",
    "hardened_serve",
    "install",
    "remote_host",
    "uninstall",
]
