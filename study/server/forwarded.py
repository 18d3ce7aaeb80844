"""The client's address behind a trusted reverse proxy (``serve --trusted-proxy ADDR``).

Behind a TLS proxy every connection comes from the proxy's address, so per-address limits
would treat all participants as one, and the logs would name only the proxy. For a connection
whose peer is a trusted proxy, :func:`client_address` takes the address the proxy appended:
the last entry of ``X-Forwarded-For`` (all such headers read in order), else the ``for=`` of
the last element of ``Forwarded`` (RFC 7239). Entries before the last were sent by the client
and may be forged, so they are never used; neither is any header from a peer that is not a
trusted proxy. A last entry that is not an IP address (``unknown``, an obfuscated ``_id``, a
malformed value) leaves the proxy's own address.

The proxy must append to ``X-Forwarded-For`` (nginx: ``proxy_add_x_forwarded_for``; Caddy does
by default), or a client's own header would pass through it as the last entry.

:func:`accepted_hosts`: the host names the ``Origin`` check accepts for a connection: its
``Host`` header, and from a trusted proxy also the public name it forwards
(``X-Forwarded-Host``, else ``Forwarded``'s ``host=``).
"""

from __future__ import annotations

import ipaddress
from collections.abc import Iterable
from typing import Any

from study.errors import StudyError

Network = ipaddress.IPv4Network | ipaddress.IPv6Network
MAX_HEADER = 2048
"""Longest forwarding entry read (a longer one is not a proxy's: the peer's address stays)."""


class ProxyAddressError(StudyError, ValueError):
    """A ``--trusted-proxy`` value that is neither an IP address nor a network."""


def trusted_networks(values: Iterable[str]) -> tuple[Network, ...]:
    """``--trusted-proxy`` values (addresses or networks such as ``10.0.0.0/8``) as networks;
    ``ProxyAddressError`` naming the value that is neither."""
    out = []
    for value in values:
        try:
            out.append(ipaddress.ip_network(str(value).strip(), strict=False))
        except ValueError:
            raise ProxyAddressError(
                f"--trusted-proxy {value!r} is not an IP address or network (e.g. 127.0.0.1 or"
                " 10.0.0.0/8)"
            ) from None
    return tuple(out)


def is_trusted(peer: str, trusted: tuple[Network, ...]) -> bool:
    if not trusted:
        return False
    try:
        address = ipaddress.ip_address(peer)
    except ValueError:
        return False
    return any(address in net for net in trusted)


def client_address(peer: str, headers: Any, *, trusted: tuple[Network, ...]) -> str:
    """The client's address: the one the trusted proxy ``peer`` appended, else ``peer``."""
    if headers is None or not is_trusted(peer, trusted):
        return peer
    xff = _last(headers, "X-Forwarded-For")
    if xff is not None:
        entry = xff
    else:
        forwarded = _last(headers, "Forwarded")
        if forwarded is None:
            return peer
        entry = _param(forwarded, "for") or ""
    return _ip(entry) or peer


def accepted_hosts(peer: str, headers: Any, *, trusted: tuple[Network, ...]) -> frozenset[str]:
    """Host names (``host`` or ``host:port``, lower case) an ``Origin`` may carry here."""
    hosts = {str(headers.get("Host", "")).lower()} if headers is not None else set()
    if headers is not None and is_trusted(peer, trusted):
        public = _last(headers, "X-Forwarded-Host")
        if public is not None:
            hosts.add(public.strip().lower())
        elif (forwarded := _last(headers, "Forwarded")) is not None:
            host = _param(forwarded, "host")
            if host:
                hosts.add(host.lower())
    hosts.discard("")
    return frozenset(h for h in hosts if not any(ch in h for ch in "@/\\?# "))


def _last(headers: Any, name: str) -> str | None:
    """The last comma-separated entry of the last ``name`` header (the one the proxy
    appended), ``None`` if there is no such header. However long the headers are (a client
    can make them long), their presence decides: a long ``X-Forwarded-For`` never lets a
    ``Forwarded`` header the client wrote take its place; an entry longer than
    ``MAX_HEADER`` is "" (not an address)."""
    values = headers.get_all(name) if hasattr(headers, "get_all") else [headers.get(name)]
    values = [str(v) for v in values if v is not None]
    if not values:
        return None
    entry = values[-1].rpartition(",")[2]
    return entry if len(entry) <= MAX_HEADER else ""


def _param(element: str, name: str) -> str | None:
    """``name=value`` of one ``Forwarded`` element (quotes removed)."""
    for pair in element.split(";"):
        key, sep, value = pair.strip().partition("=")
        if sep and key.strip().lower() == name:
            return value.strip().strip('"')
    return None


def _ip(entry: str) -> str | None:
    """``entry`` as an IP address (``[v6]:port``, ``v4:port`` and brackets allowed)."""
    text = entry.strip().strip('"')
    if text.startswith("["):
        text = text[1 : text.find("]")] if "]" in text else ""
    elif text.count(":") == 1:
        text = text.split(":")[0]
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        return None


__all__ = ["accepted_hosts", "client_address", "is_trusted", "trusted_networks"]
