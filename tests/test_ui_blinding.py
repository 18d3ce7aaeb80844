"""The blinding guard drops any participant-bound message naming a condition, and only those."""

from __future__ import annotations

import asyncio

import viser
import websockets

from study.server import blinding
from study.server.blinding import BlindingGuard, BlindingViolation, check_text, find_condition_words
from tests.browser.harness import decode_frame, iter_strings, run_async


def received_messages(port: int, *, seconds: float = 1.0) -> list[dict]:
    """Messages a bare websocket client receives from a viser server in ``seconds``."""

    async def run() -> list[dict]:
        out: list[dict] = []
        async with websockets.connect(
            f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"]
        ) as ws:
            loop = asyncio.get_running_loop()
            end = loop.time() + seconds
            while (left := end - loop.time()) > 0:
                try:
                    out.extend(decode_frame(await asyncio.wait_for(ws.recv(), left)))
                except TimeoutError:
                    break
        return out

    return run_async(run())


def test_every_condition_word_is_found_case_insensitively() -> None:
    for word in ("Timid", "AGGRESSIVE", "right", "Wrong", "easy", "hard"):
        assert find_condition_words(f"the robot was {word} here") == [word.lower()]
    assert find_condition_words("top right corner") == ["right"]
    assert find_condition_words("Please pick up the farther object.") == []


def test_check_text_raises_with_the_word() -> None:
    try:
        check_text("this one is hard")
    except BlindingViolation as exc:
        assert "hard" in str(exc)
    else:  # pragma: no cover
        raise AssertionError("a condition word passed check_text")


def test_guard_walks_nested_strings_and_keys() -> None:
    guard = BlindingGuard()
    assert guard.allow({"a": ["fine", ("also fine",)]})
    assert not guard.allow({"a": ["fine", ("mode timid",)]})
    assert not guard.allow({"aggressive": 1})
    assert [v.words for v in guard.violations] == [("timid",), ("aggressive",)]


def test_installed_guard_blocks_only_the_guarded_server() -> None:
    guarded = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    other = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        guard = blinding.install(guarded)
        guarded.gui.add_markdown("Pick up the farther object")
        assert guard.violations == []
        guarded.gui.add_markdown("You are in the easy condition")
        assert [v.words for v in guard.violations] == [("easy",)]
        before = guard.checked
        other.gui.add_markdown("Condition: hard / wrong / aggressive")  # experimenter side
        assert guard.checked == before and len(guard.violations) == 1
        # What a browser connecting now receives: the clean text, never the condition word
        # (viser rewrote the queued creation message in place; the wire layer blanks it).
        texts = [s for m in received_messages(guarded.get_port()) for s in iter_strings(m)]
        assert any("farther object" in s for s in texts)
        assert not any("easy" in s.lower() for s in texts)
        assert guard.redacted >= 1
    finally:
        blinding.uninstall(guarded)
        guarded.stop()
        other.stop()
