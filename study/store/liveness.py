"""Is the process that holds a session lease (``study.store.lease``) still alive?

A lease row stores the holder's pid, host, process start time and a heartbeat. On the same host
the holder is live while its pid exists, is not a zombie and has the same start time (so a
recycled pid does not count); on another host the heartbeat must be fresher than ``stale_after_s``.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path

HOST = socket.gethostname()


def process_start(pid: int) -> str:
    """The kernel's start time of ``pid`` (clock ticks since boot) or ``""`` if unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return ""
    fields = stat[stat.rfind(")") + 2 :].split()
    return fields[19] if len(fields) > 19 else ""


def _zombie(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rfind(")") + 2 :].startswith("Z")


def pid_alive(pid: int, *, started: str = "") -> bool:
    """Whether ``pid`` runs on this host (and, if ``started`` is given, is the same process)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    if _zombie(pid):
        return False
    return not (started and process_start(pid) not in ("", started))


def holder_is_live(
    *, pid: int, host: str, started: str, heartbeat_age_s: float, stale_after_s: float
) -> bool:
    """Whether a lease holder must be respected (see module docstring)."""
    if host == HOST:
        return pid_alive(pid, started=started)
    return heartbeat_age_s < stale_after_s
