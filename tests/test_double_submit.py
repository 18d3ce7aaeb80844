"""A double click on the questions' Continue submits the answers once.

viser runs button callbacks in a thread pool, so two clicks read together ran at once and both
submitted; with a protocol that asks an item after each run and again after each task, the copy
answered the next screen's item of the same id (a hostile client's report: 4 of 4 such answers
were copies). Here the tab answers the paper's after-run items and sends Continue twice in one
go, while the session takes its time to store the first.
"""

from __future__ import annotations

import asyncio
import threading
import time
from typing import Any

import viser

from study.protocol import load_protocol
from tests.browser.harness import run_async
from tests.protocol_copies import PAPER_PROTOCOL
from tests.support.raw_client import RawClient, bare_page


def test_two_clicks_on_continue_read_together_submit_the_answers_once() -> None:
    protocol = load_protocol(PAPER_PROTOCOL)
    items = list(protocol.questionnaire.after_run)
    submitted: list[dict[str, object]] = []
    lock = threading.Lock()

    def on_submit(answers: dict[str, object]) -> None:
        with lock:
            submitted.append(dict(answers))
        time.sleep(0.3)  # the store write and the next screen take a moment

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)

    async def run() -> None:
        async with RawClient(server.get_port()) as tab:
            page = await bare_page(server, words=protocol.condition_words)
            loop = asyncio.get_running_loop()
            await loop.run_in_executor(
                None,
                lambda: page.show_questions(
                    "Run 1 of 8", "", items, progress=None, on_submit=on_submit
                ),
            )
            groups: list[dict[str, Any]] = []
            for _ in range(100):
                groups = [m for m in tab.messages if m.get("type") == "GuiButtonGroupMessage"]
                if len(groups) == len(items):
                    break
                await asyncio.sleep(0.05)
            assert len(groups) == len(items), "the screen's answer rows never arrived"
            for group in groups:
                await tab.send("GuiUpdateMessage", uuid=group["uuid"], updates={"value": "4"})
            await asyncio.sleep(0.5)  # the answers are in; Continue is enabled
            button = await tab.button("Continue")
            for _ in range(2):  # a double click, both read at once
                await tab.send("GuiUpdateMessage", uuid=button, updates={"value": True})
            await asyncio.sleep(1.0)

    try:
        run_async(run())
    finally:
        server.stop()
    assert len(submitted) == 1, f"{len(submitted)} submissions of one screen"
    assert submitted[0] == {i.id: 4 for i in items}
