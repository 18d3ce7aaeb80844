"""Room for connections: the process's limit on open files raised to what it may have.

Every connection is an open file. At the soft limit most systems start a process with
(1024), a few hundred addresses holding silent connections exhausted it: asyncio stopped
accepting ("socket.accept() out of system resource") and honest page loads waited 1.5-7.2 s
(an attacker's pass, ``benchmarks/README.md``). ``serve`` raises the soft limit to the hard one
(often 2^19 or more; at least what the listening sockets, the store and the logs need).
"""

from __future__ import annotations

try:
    import resource
except ImportError:  # not a POSIX system: nothing to raise
    resource = None  # type: ignore[assignment]


def raise_open_files_limit() -> tuple[int, int]:
    """Raise this process's soft limit on open files to its hard limit; returns ``(before,
    after)`` (``(-1, -1)`` where the system has no such limit). A refusal leaves it as it was."""
    if resource is None:
        return -1, -1
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard == resource.RLIM_INFINITY or soft == hard:
        return soft, soft
    try:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    except (OSError, ValueError):
        return soft, soft
    return soft, hard
