"""Values the store checks: participant pseudonyms, status vocabularies, timestamps."""

from __future__ import annotations

import re
from datetime import UTC, datetime
from pathlib import Path

from study.store.errors import InvalidParticipantIdError

PARTICIPANT_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$")
SESSION_STATUSES = ("enrolled", "running", "completed", "withdrawn", "ended")
TRIAL_STATUSES = ("running", "completed", "redone", "skipped", "interrupted")


def now_iso() -> str:
    """The current UTC time, ISO 8601 with microseconds (the store's timestamp format)."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


def check_participant_id(participant: str) -> str:
    """Return ``participant`` if it is a valid pseudonym, else raise ``InvalidParticipantIdError``."""
    if not isinstance(participant, str) or not PARTICIPANT_ID.match(participant):
        raise InvalidParticipantIdError(
            f"participant ID {participant!r} is not a pseudonym: use 1-32 letters, digits, '-' "
            "or '_', starting with a letter or digit (e.g. 'P01'); never a name or e-mail"
        )
    return participant


def unknown_participant(participant: str, path: Path | None) -> str:
    where = f" in {path}" if path else ""
    return (
        f"participant {participant} is not enrolled{where}; check the ID, or start a new "
        "session without --resume to enrol them"
    )
