"""Hostile clients of the participant port, run as their own process (on the same cores).

``python -m tests.attacker KIND --port P [--addresses A] [--tasks T] [--seconds S] ...`` runs
one attack from the loopback addresses 127.0.0.2 onwards (never another machine) and prints a
JSON line of what it managed on stdout, at the end of ``seconds`` or on SIGTERM (a test that
has seen what it needs stops it early). The kinds:

* ``storm``: ``tasks`` tasks open a websocket, send a camera message (so the server builds a
  page), wait 50 ms and close, over and over (a reconnect loop; no code needed);
* ``tcp``: bare TCP connections opened and closed at once;
* ``flood``: ``tasks`` sockets per address, each sending ``rate`` camera messages a second;
* ``idle``: as many sockets as the server lets in, held without a word, re-opened when closed;
* ``lurk``: the same, but each sends its camera first (a tab idling on the join screen);
* ``guess``: tabs typing wrong join codes as fast as the server answers, re-opened when
  throttled;
* ``version``: websocket handshakes offering a 7 KB subprotocol of another viser version.

Used by ``tests/test_port_attacks.py`` and ``benchmarks/server.py``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import signal
import sys
import time
from typing import Any

import msgspec
import viser
import websockets

CAMERA = msgspec.msgpack.encode(
    {
        "type": "ViewerCameraMessage",
        "wxyz": [1.0, 0.0, 0.0, 0.0],
        "position": [-1.0, 0.0, 1.0],
        "fov": 1.0,
        "near": 0.01,
        "far": 100.0,
        "image_height": 600,
        "image_width": 800,
        "look_at": [0.45, 0.0, 0.15],
        "up_direction": [0.0, 0.0, 1.0],
    }
)
SUBPROTOCOL = f"viser-v{viser.__version__}"
ALPHABET = "ACDEFHJKMNPQRTUVWXY3479"


def addresses(n: int) -> list[str]:
    """``n`` loopback source addresses other than 127.0.0.1 (the honest tab's)."""
    return [f"127.0.0.{2 + k}" for k in range(n)]


async def _connect(port: int, address: str, **kw: Any) -> Any:
    return await websockets.connect(
        f"ws://127.0.0.1:{port}",
        subprotocols=[kw.pop("subprotocol", SUBPROTOCOL)],
        local_addr=(address, 0),
        open_timeout=5,
        close_timeout=1,
        max_queue=4,
        **kw,
    )


async def storm(port: int, address: str, end: float, stats: dict[str, int]) -> None:
    while time.monotonic() < end:
        try:
            async with await _connect(port, address) as ws:
                await ws.send(CAMERA)
                await asyncio.sleep(0.05)
            stats["opened"] += 1
        except Exception:
            stats["refused"] += 1
            await asyncio.sleep(0.01)


async def tcp(port: int, address: str, end: float, stats: dict[str, int]) -> None:
    while time.monotonic() < end:
        try:
            _, writer = await asyncio.open_connection("127.0.0.1", port, local_addr=(address, 0))
            writer.close()
            stats["opened"] += 1
        except Exception:
            stats["refused"] += 1
            await asyncio.sleep(0.01)


async def flood(port: int, address: str, end: float, stats: dict[str, int], rate: float) -> None:
    with contextlib.suppress(Exception):
        async with await _connect(port, address) as ws:
            stats["opened"] += 1
            due = time.monotonic()
            while time.monotonic() < end:
                await ws.send(CAMERA)
                stats["sent"] += 1
                due += 1.0 / rate
                await asyncio.sleep(max(0.0, due - time.monotonic()))
            return
    stats["refused"] += 1


async def idle(
    port: int, address: str, end: float, stats: dict[str, int], *, greet: bool = False
) -> None:
    while time.monotonic() < end:
        try:
            ws = await _connect(port, address, ping_interval=None)
            if greet:
                await ws.send(CAMERA)
        except Exception:
            stats["refused"] += 1
            await asyncio.sleep(0.2)
            continue
        stats["opened"] += 1
        stats["held"] += 1
        with contextlib.suppress(Exception):
            await asyncio.wait_for(ws.wait_closed(), timeout=max(0.0, end - time.monotonic()))
        stats["held"] -= 1
        with contextlib.suppress(Exception):
            await ws.close()


async def lurk(port: int, address: str, end: float, stats: dict[str, int]) -> None:
    await idle(port, address, end, stats, greet=True)


async def guess(port: int, address: str, end: float, stats: dict[str, int]) -> None:
    k = 0
    while time.monotonic() < end:
        try:
            async with await _connect(port, address) as ws:
                stats["opened"] += 1
                await ws.send(CAMERA)
                text = button = None
                async for frame in ws:
                    for m in _messages(frame):
                        props = m.get("props") or {}
                        if m.get("type") == "GuiTextMessage" and props.get("label") == "Join code":
                            text = m["uuid"]
                        if m.get("type") == "GuiButtonMessage" and props.get("label") == "Join":
                            button = m["uuid"]
                        if "Too many tries" in str(props.get("_markdown", "")):
                            raise ConnectionAbortedError
                    if text and button:
                        k += 1
                        code = "".join(ALPHABET[(k * 7 + j) % len(ALPHABET)] for j in range(6))
                        for uuid, value in ((text, code), (button, True)):
                            msg = {
                                "type": "GuiUpdateMessage",
                                "uuid": uuid,
                                "updates": {"value": value},
                            }
                            await ws.send(msgspec.msgpack.encode(msg))
                        stats["guesses"] += 1
                        text = button = None
                    if time.monotonic() > end:
                        break
        except ConnectionAbortedError:
            stats["throttled"] += 1
        except Exception:
            stats["refused"] += 1
            await asyncio.sleep(0.05)


async def version(port: int, address: str, end: float, stats: dict[str, int]) -> None:
    other = "viser-v" + "9" * 7000
    while time.monotonic() < end:
        try:
            async with await _connect(port, address, subprotocol=other):
                stats["opened"] += 1
        except Exception:
            stats["refused"] += 1
            await asyncio.sleep(0.005)


def _messages(frame: bytes | str) -> list[dict[str, Any]]:
    if isinstance(frame, str):
        return []
    import zstandard

    inner_len = int.from_bytes(frame[0:8], "little")
    comp_len = int.from_bytes(frame[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(
        frame[16 : 16 + comp_len], max_output_size=inner_len
    )
    return list(msgspec.msgpack.decode(inner).get("messages", ()))


KINDS = {
    "storm": storm,
    "tcp": tcp,
    "flood": flood,
    "idle": idle,
    "lurk": lurk,
    "guess": guess,
    "version": version,
}


async def attack(
    kind: str, *, port: int, n_addresses: int, tasks: int, seconds: float, rate: float
) -> dict[str, Any]:
    stats: dict[str, int] = dict.fromkeys(
        ("opened", "refused", "sent", "held", "guesses", "throttled"), 0
    )
    end = time.monotonic() + seconds
    sources = addresses(n_addresses)
    run = KINDS[kind]
    extra = (rate,) if kind == "flood" else ()
    jobs = [
        run(port, sources[k % n_addresses], end, stats, *extra)
        for k in range(tasks * (n_addresses if kind == "flood" else 1))
    ]
    running = asyncio.gather(*jobs)
    asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, running.cancel)
    started = time.monotonic()
    with contextlib.suppress(asyncio.CancelledError):
        await running
    return {"kind": kind, "addresses": n_addresses, "seconds": seconds, **stats} | {
        "ran_s": round(time.monotonic() - started, 2)
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=sorted(KINDS))
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--addresses", type=int, default=8)
    parser.add_argument("--tasks", type=int, default=32, help="tasks in all (flood: per address)")
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument(
        "--rate", type=float, default=40.0, help="flood: messages a second per socket"
    )
    args = parser.parse_args()
    result = asyncio.run(
        attack(
            args.kind,
            port=args.port,
            n_addresses=args.addresses,
            tasks=args.tasks,
            seconds=args.seconds,
            rate=args.rate,
        )
    )
    print(json.dumps(result), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
