"""Whose data may be kept: the answer to the protocol's end-of-study retention question.

A consent that says finished runs are "kept only if you agree" is honoured by asking at the
end (a ``retention`` item, ``study.protocol.questionnaire.RetentionItem``) and by keeping out
of every export and analysis a participant who did not agree: one who chose another option
(declined), and one whose session is over without an answer (withdrew, or was ended early). A
session still under way (enrolled, running) has not reached the question: its data are
exported as they stand, listed as pending (``RetentionDecisions.pending``), and an export made
after it ends decides. A protocol without a retention item keeps everyone.

The store itself keeps what was recorded (``Store.discard_participant`` is for data that can
be made again); this module decides what leaves it. A participant who stopped before the
question (withdrew, or was ended) may still be asked, in person: :func:`record_retention`
(``python -m study retention``) records their answer afterwards, marked as recorded by the
experimenter (``questionnaire = "recorded"`` in the answers table and a ``retention_recorded``
event).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from study.store import StoreError

if TYPE_CHECKING:
    from study.protocol import Protocol
    from study.store import Store

RECORDED = "recorded"
"""The ``questionnaire`` of a retention answer the experimenter recorded after the session."""
RECORDED_STEP = -1
"""Its ``step``: outside the session's plan."""
FINAL = ("withdrawn", "ended", "completed")
UNDER_WAY = ("enrolled", "running")
"""Session statuses that have not reached the end-of-study question yet."""


class RetentionError(StoreError):
    """A retention answer cannot be recorded (no such question, session still running, already
    answered); the message says what to do."""


@dataclass(frozen=True)
class RetentionDecisions:
    """``kept``: participants whose data may be used; ``excluded``: everyone else, with why;
    ``pending``: kept participants whose session has not reached the question yet (their
    status); ``answers``: each participant's retention answer as given (``None``: none)."""

    kept: frozenset[str]
    excluded: dict[str, str] = field(default_factory=dict)
    pending: dict[str, str] = field(default_factory=dict)
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
    pending: dict[str, str] = {}
    for p in everyone:
        if p not in given and status.get(p) in UNDER_WAY:
            pending[p] = status[p]
        elif p not in given:
            excluded[p] = (
                f"did not answer the data-retention question (session {status.get(p, '?')})"
            )
        elif not item.keeps(given[p]):
            excluded[p] = f"declined data retention (answered {given[p]!r})"
    kept = frozenset(p for p in everyone if p not in excluded)
    return RetentionDecisions(
        kept=kept,
        excluded=excluded,
        pending=pending,
        answers={p: given.get(p) for p in everyone},
    )


def record_retention(store: Store, protocol: Protocol, participant: str, *, keep: bool) -> str:
    """Record ``participant``'s answer to the retention question, asked by the experimenter
    after their session stopped (module docstring); returns the option recorded. Raises
    :class:`RetentionError` when the protocol asks none, the session is not over (the page
    asks it at the end), or an answer is already recorded."""
    item = protocol.questionnaire.retention
    if item is None:
        raise RetentionError(
            f"protocol {protocol.id!r} asks no data-retention question: every participant's "
            "data are kept"
        )
    session = store.session(participant)
    if session.status not in FINAL:
        raise RetentionError(
            f"{participant}'s session is {session.status}; the page asks the retention question "
            "at its end -- record an answer only after a session stopped"
        )
    given = [a for a in store.answers(participant=participant) if a.item == item.id]
    if given:
        raise RetentionError(
            f"{participant} already answered the retention question ({given[-1].value!r})"
        )
    option = item.keep if keep else next(o for o in item.options if o != item.keep)
    with store.transaction() as tx:
        tx.add_answer(
            session_id=session.session_id,
            participant=participant,
            step=RECORDED_STEP,
            questionnaire=RECORDED,
            item=item.id,
            kind=item.kind,
            value=option,
        )
        tx.event(
            session.session_id,
            participant,
            "retention_recorded",
            {"item": item.id, "keep": keep, "by": "experimenter"},
        )
    return option


__all__ = ["RetentionDecisions", "RetentionError", "record_retention", "retention_decisions"]
