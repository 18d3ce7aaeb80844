"""Playwright helpers shared by the browser tests and benchmarks/server.py.

Chromium is Debian's (``/usr/bin/chromium``), never a downloaded one. viser sends each window
of messages as one binary websocket frame: two little-endian uint64 (msgpack size, compressed
size), the zstd-compressed msgpack ``{"messages": [...], ...}``, then raw binary buffers;
:func:`decode_frame` returns the message dicts.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import msgspec
import numpy as np
import viser
import viser.transforms as vtf
import zstandard

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-sync",
]


def launch(playwright: Any) -> Any:
    """Start headless Debian Chromium."""
    return playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)


def decode_frame(payload: bytes | str) -> list[dict[str, Any]]:
    """Messages carried by one viser websocket frame (server to browser)."""
    if isinstance(payload, str):
        return []
    inner_len = int.from_bytes(payload[0:8], "little")
    comp_len = int.from_bytes(payload[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(
        payload[16 : 16 + comp_len], max_output_size=inner_len
    )
    decoded = msgspec.msgpack.decode(inner)
    return list(decoded.get("messages", ()))


def iter_strings(obj: Any) -> Iterator[str]:
    if isinstance(obj, str):
        yield obj
    elif isinstance(obj, dict):
        for k, v in obj.items():
            if isinstance(k, str):
                yield k
            yield from iter_strings(v)
    elif isinstance(obj, list | tuple):
        for v in obj:
            yield from iter_strings(v)


@dataclass
class FrameLog:
    """Every frame a page's websockets received, with its arrival time (thread-safe)."""

    frames: list[tuple[float, bytes]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def attach(self, page: Any) -> FrameLog:
        def on_ws(ws: Any) -> None:
            def on_frame(payload: Any) -> None:
                if isinstance(payload, bytes | bytearray):
                    with self.lock:
                        self.frames.append((time.monotonic(), bytes(payload)))

            ws.on("framereceived", on_frame)

        page.on("websocket", on_ws)
        return self

    def messages(self) -> list[dict[str, Any]]:
        with self.lock:
            frames = list(self.frames)
        out: list[dict[str, Any]] = []
        for _, payload in frames:
            out.extend(decode_frame(payload))
        return out

    def strings(self) -> list[str]:
        return [s for m in self.messages() for s in iter_strings(m)]


def project(camera: viser.CameraHandle, point: np.ndarray) -> tuple[float, float]:
    """Pixel (x, y) of world ``point`` in ``camera``'s image (OpenCV camera axes)."""
    rot = vtf.SO3(np.asarray(camera.wxyz)).as_matrix()
    pc = rot.T @ (np.asarray(point, float) - np.asarray(camera.position))
    f = (camera.image_height / 2) / np.tan(camera.fov / 2)
    return (
        float(f * pc[0] / pc[2] + camera.image_width / 2),
        float(f * pc[1] / pc[2] + camera.image_height / 2),
    )


def drag(page: Any, start: tuple[float, float], end: tuple[float, float], *, steps: int = 12):
    """Press at ``start``, move to ``end`` in ``steps`` moves, release (slow software WebGL)."""
    page.mouse.move(*start)
    page.wait_for_timeout(250)
    page.mouse.down()
    page.wait_for_timeout(250)
    for k in range(1, steps + 1):
        a = k / steps
        page.mouse.move(start[0] + a * (end[0] - start[0]), start[1] + a * (end[1] - start[1]))
        page.wait_for_timeout(80)
    page.wait_for_timeout(250)
    page.mouse.up()


def wait_until(predicate: Any, *, timeout: float = 20.0, interval: float = 0.05) -> bool:
    """Poll ``predicate()`` until truthy or ``timeout`` seconds pass; return its last value."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value or time.monotonic() > deadline:
            return bool(value)
        time.sleep(interval)
