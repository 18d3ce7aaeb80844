"""Inbound firewall for a viser server: what a browser may send, and how much.

viser decodes every websocket message a browser sends on the server's event loop and
dispatches it to whatever handler is registered for its type -- among them
``ShareUrlRequest``, which opens a public tunnel. A :class:`Firewall` stands in front of that
(through :mod:`study.server.viser_door`), in parts:

* ``port_config``: :class:`FirewallConfig`, every limit of one port;
* ``rules``: what one message may carry (types, sizes, values);
* ``limits``: how much one connection may send;
* ``shares``: fair shares of the server's time for connections that hold no session (messages
  and new connections, per address);
* ``slots``: who holds the port's connection slots, timeouts, and who gets one next;
* ``door``: the checks before a request is read and at the websocket handshake;
* ``notes``: log lines a client can cause, rate-limited;
* ``port``: the :class:`Firewall` itself -- the door, and the limits and rules applied to
  every frame and message;
* ``hooks``: where it stands in front of a viser server (:func:`start_server`,
  :func:`install`).
"""

from study.server.firewall.door import REJOIN_COOKIE, Door, remote_host
from study.server.firewall.hooks import install, start_server, uninstall
from study.server.firewall.port import Firewall
from study.server.firewall.port_config import FirewallConfig
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
    "Door",
    "Dropped",
    "Firewall",
    "FirewallConfig",
    "RefusedMessage",
    "check_values",
    "install",
    "remote_host",
    "start_server",
    "uninstall",
]
