"""The blinded vocabulary comes from the protocol, and the guard drops any participant-bound
message naming a condition of the protocol it serves, and only those."""

from __future__ import annotations

import asyncio

import pytest
import viser
import websockets

from study.protocol import BlindingError, load_protocol, parse_protocol
from study.protocol.blinding import FIXED_WORDS, find_words
from study.server import blinding_guard
from study.server.blinding_guard import BlindingGuard, BlindingViolation, check_text
from tests.browser.harness import decode_frame, iter_strings, run_async
from tests.protocol_copies import PAPER_PROTOCOL, PROTOCOLS, STUDY_PROTOCOLS

PAPER_WORDS = FIXED_WORDS


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


def test_the_shipped_study_protocols_are_all_listed() -> None:
    """STUDY_PROTOCOLS drives the blinding tests: a new protocol file must join it."""
    shipped = {p for p in PROTOCOLS.glob("*.toml") if "[factors]" in p.read_text()}
    assert shipped == set(STUDY_PROTOCOLS)


@pytest.mark.parametrize("path", STUDY_PROTOCOLS, ids=lambda p: p.stem)
def test_every_level_task_and_mode_of_a_protocol_is_blinded(path) -> None:
    p = load_protocol(path)
    words = p.condition_words
    assert set(FIXED_WORDS) <= set(words) and len(set(words)) == len(words)
    for levels in p.factors.values():
        assert {w.lower() for w in levels} <= set(words)
    assert set(p.task_names) <= set(words) and set(p.mode_names) <= set(words)


def test_memory3_levels_are_blinded() -> None:
    """The issue's case: memory3's own levels, which the old fixed list did not hold."""
    words = load_protocol(PROTOCOLS / "memory3.toml").condition_words
    for level in ("standard", "amnesic", "memory", "oracle", "linear"):
        assert level in words


def test_a_renamed_level_is_blinded_in_texts_and_object_names() -> None:
    text = PAPER_PROTOCOL.read_text(encoding="utf-8")
    renamed = text.replace('mode = ["timid"', 'mode = ["gentle"').replace(
        "[modes.timid]", "[modes.gentle]"
    )
    assert "gentle" in parse_protocol(renamed).condition_words
    with pytest.raises(BlindingError, match=r"'gentle'.*rephrase"):
        parse_protocol(renamed.replace("Thank you for taking part!", "Thank you, gentle one!"))
    with pytest.raises(BlindingError, match=r"objects\[\d\]\.name.*neutral object name"):
        parse_protocol(renamed.replace('name = "bottle"', 'name = "gentle_bottle"', 1))


@pytest.mark.parametrize("word", FIXED_WORDS)
def test_fixed_words_in_object_names_are_refused_on_load(word: str) -> None:
    with pytest.raises(BlindingError, match=rf"\['{word}'\].*neutral object name"):
        parse_protocol(PAPER_PROTOCOL.read_text().replace('"mug"', f'"{word}_mug"'))


def test_every_condition_word_is_found_case_insensitively() -> None:
    for word in ("Timid", "AGGRESSIVE", "right", "Wrong", "easy", "hard"):
        assert find_words(f"the robot was {word} here", PAPER_WORDS) == [word.lower()]
    assert find_words("top right corner", PAPER_WORDS) == ["right"]
    assert find_words("Please pick up the farther object.", PAPER_WORDS) == []


def test_check_text_raises_with_the_word() -> None:
    with pytest.raises(BlindingViolation, match="hard"):
        check_text("this one is hard", words=PAPER_WORDS)
    with pytest.raises(BlindingViolation, match="oracle"):
        check_text("the Oracle helps", words=(*PAPER_WORDS, "oracle"))


def test_a_guard_needs_words() -> None:
    with pytest.raises(ValueError, match="non-empty"):
        BlindingGuard(words=())


def test_guard_walks_nested_strings_and_keys() -> None:
    guard = BlindingGuard(words=PAPER_WORDS)
    assert guard.allow({"a": ["fine", ("also fine",)]})
    assert not guard.allow({"a": ["fine", ("mode timid",)]})
    assert not guard.allow({"aggressive": 1})
    assert [v.words for v in guard.violations] == [("timid",), ("aggressive",)]


def test_installed_guard_blocks_only_the_guarded_server() -> None:
    guarded = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    other = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        words = load_protocol(PROTOCOLS / "memory3.toml").condition_words
        guard = blinding_guard.install(guarded, words=words)
        guarded.gui.add_markdown("Pick up the farther object")
        assert guard.violations == []
        guarded.gui.add_markdown("You are in the easy condition")
        guarded.gui.add_markdown("The Oracle predicts")  # a level of memory3 only
        assert [v.words for v in guard.violations] == [("easy",), ("oracle",)]
        before = guard.checked
        other.gui.add_markdown("Condition: hard / wrong / aggressive")  # experimenter side
        assert guard.checked == before and len(guard.violations) == 2
        # What a browser connecting now receives: the clean text, never the condition word
        # (viser rewrote the queued creation message in place; the wire layer blanks it).
        texts = [s for m in received_messages(guarded.get_port()) for s in iter_strings(m)]
        assert any("farther object" in s for s in texts)
        assert not any(find_words(s, words) for s in texts)
        assert guard.redacted >= 1
    finally:
        blinding_guard.uninstall(guarded)
        guarded.stop()
        other.stop()


def test_viser_settings_that_equal_a_level_pass_and_nothing_else_does() -> None:
    """memory3's level "standard" is also viser's default mesh material: that exact value of
    that field passes (it is the same in every condition); anywhere else it is blocked."""
    guard = BlindingGuard(words=(*PAPER_WORDS, "standard"))
    assert guard.allow({"props": {"material": "standard", "name": "/arm"}})
    assert not guard.allow({"props": {"material": "standard-ish"}})
    assert not guard.allow({"props": {"content": "standard"}})
    assert not guard.allow({"props": {"name": "standard"}})
    assert guard.redact({"material": "standard", "label": "standard"}, message_type="m") == {
        "material": "standard",
        "label": "",
    }
