"""``FirewallConfig``: every limit of one port's :class:`~study.server.firewall.Firewall`.

The defaults are the participant port's. The console's port takes every message type and much
larger messages from the experimenter's own tabs (``study.server.server``); tests and
benchmarks pass other limits (``dataclasses.replace`` or keywords).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from study.server.firewall.rules import MAX_MESSAGE_BYTES, MAX_POSITION_M, PARTICIPANT_TYPES
from study.server.forwarded import Network


@dataclass(frozen=True)
class FirewallConfig:
    """The limits of one port, in groups:

    * what a message may carry (``rules``): ``allowed`` message types (``None``: every type and
      no value rules -- the console), ``allow_share`` (share-link types), ``max_bytes``,
      ``max_position_m``;
    * how much one connection may send (``limits.ConnectionRate``): ``rate_per_s`` messages a
      second with a ``burst``, ``backlog_s`` seconds of credit after a stall, at most
      ``max_refused`` refused messages;
    * how much connections without a session may take (``shares``): ``shares_per_s`` per
      address (``None``: no shares); a bound tab waits only past ``bound_bytes_per_s`` (burst
      ``bound_bytes_burst``);
    * who gets in (``door``, ``slots``): new TCP connections ``accept_per_s`` per address
      (burst ``accept_burst``, ``accept_total_per_s`` in all; ``None``: no gate), new tabs
      ``new_tabs_per_s`` per address (``new_tabs_burst``, ``new_tabs_total_per_s``; ``None``:
      no gate), ``max_connections`` in all and ``max_connections_per_address``, closed after
      ``greet_timeout_s`` without a message or ``idle_timeout_s`` on the join screen
      (``None``: never), the ``Origin`` check (``check_origin``), only this machine's names
      (``loopback_only``), ``trusted_proxies`` whose forwarded client address counts
      (``study.server.forwarded``);
    * what one connection may do below a message (``limits.FrameBudget``): a message in at most
      ``max_fragments`` frames, at most ``pings_per_s`` pings a second (burst ``ping_burst``);
    * one log line per refusal reason every ``log_every_s`` seconds at most.
    """

    allowed: Iterable[str] | None = PARTICIPANT_TYPES
    allow_share: bool = False
    max_bytes: int = MAX_MESSAGE_BYTES
    max_position_m: float = MAX_POSITION_M
    rate_per_s: float = 200.0
    burst: float = 400.0
    backlog_s: float = 10.0
    max_refused: int = 200
    shares_per_s: float | None = 400.0
    bound_bytes_per_s: float | None = 128 * 1024
    bound_bytes_burst: float = 1024 * 1024
    accept_per_s: float | None = 1.0
    accept_burst: float = 12.0
    accept_total_per_s: float = 40.0
    new_tabs_per_s: float | None = 0.2
    new_tabs_burst: float = 6.0
    new_tabs_total_per_s: float = 2.0
    max_connections: int = 64
    max_connections_per_address: int = 8
    greet_timeout_s: float = 15.0
    idle_timeout_s: float | None = 600.0
    check_origin: bool = True
    loopback_only: bool = False
    trusted_proxies: tuple[Network, ...] = ()
    max_fragments: int = 64
    pings_per_s: float = 5.0
    ping_burst: float = 20.0
    log_every_s: float = 60.0
