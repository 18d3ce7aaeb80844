"""Whose data may be kept: the answer to the protocol's end-of-study retention question.

A consent that says finished runs are "kept only if you agree" is honoured by asking at the
end (a ``retention`` item, ``study.protocol.questionnaire.RetentionItem``) and by keeping out
of every export and analysis a participant who did not agree: one who chose another option
(declined), and one who never answered (withdrew, was ended early, or is still running: the
agreement is not there yet). A protocol without a retention item keeps everyone.

The store itself keeps what was recorded (``Store.discard_participant`` is for data that can
be made again); this module decides what leaves it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from study.protocol import Protocol
    from study.store import Store


@dataclass(frozen=True)
class RetentionDecisions:
    """``kept``: participants whose data may be used; ``excluded``: everyone else, with why;
    ``answers``: each participant's retention answer as given (``None``: none)."""

    kept: frozenset[str]
    excluded: dict[str, str] = field(default_factory=dict)
    answers: dict[str, str | None] = field(default_factory=dict)


def retention_decisions(store: Store, protocol: Protocol | None) -> RetentionDecisions:
    """Decide for every participant enrolled in ``store`` (module docstring)."""
    everyone = [p.participant for p in store.participants()]
    item = protocol.questionnaire.retention if protocol is not None else None
    if item is None:
        return RetentionDecisions(kept=frozenset(everyone))
    given: dict[str, str | None] = {}
    for a in store.answers():
        if a.item == item.id:
            given[a.participant] = a.value
    status = {s.participant: s.status for s in store.sessions()}
    excluded: dict[str, str] = {}
    for p in everyone:
        if p not in given:
            excluded[p] = (
                f"did not answer the data-retention question (session {status.get(p, '?')})"
            )
        elif not item.keeps(given[p]):
            excluded[p] = f"declined data retention (answered {given[p]!r})"
    kept = frozenset(p for p in everyone if p not in excluded)
    return RetentionDecisions(
        kept=kept, excluded=excluded, answers={p: given.get(p) for p in everyone}
    )


__all__ = ["RetentionDecisions", "retention_decisions"]
