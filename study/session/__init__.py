"""``Session``: one participant's way through the study, as a state machine over the plan.

    enrol -> [waiting] -start-> consent -agree-> training runs (unassisted) -> baseline items
          -> per task in schedule order: run, items, run, items, preference -> debrief -finish-> done

The same engine serves the study server (participant and experimenter views in a browser) and
headless runs (``python -m study run``, simulated participants). Every transition is one store
transaction that also appends an event, so a killed process leaves the store at a step boundary
(or inside a trial, which ``Session.reopen`` marks interrupted and runs again as a new attempt).

Participant actions: ``agree``, ``start_trial``, ``answer``, ``finish``.
Experimenter actions: ``start``, ``pause``, ``resume``, ``redo``, ``skip``, ``withdraw``, ``end``.
Views: ``screen()`` (blind, for the participant's browser), ``overview()`` (experimenter).

Thread-safety: every public method of ``Session`` is thread-safe (one re-entrant lock), so viser
callback threads may call them concurrently. ``TrialRun.tick`` is for the single control-loop
thread; it never takes the session lock except when its trial ends by itself, and never touches
SQLite (the ``SampleWriter`` thread does). Listeners run after the lock is released.

The engine is split by concern: ``study.session.core`` (state, lease, transactions),
``study.session.views`` (``screen``/``overview``), ``study.session.participant`` and
``study.session.experimenter`` (the actions), ``study.session.opening`` (``enrol``/``reopen``),
``study.session.store_open`` (``open_store``). Import from here: this module keeps every public name.
"""

from __future__ import annotations

from study.protocol import AnswerError  # noqa: F401
from study.schedule import Design, Enrollment, next_row  # noqa: F401
from study.session.core import (  # noqa: F401
    FINAL_STATUSES,
    Listener,
    default_trial_factory,
    trial_seed,
)
from study.session.errors import (  # noqa: F401
    MAX_SEED,
    InvalidAnswerError,
    InvalidSeedError,
    MissingReasonError,
    SessionClosedError,
    SessionError,
    SessionStateError,
    UnknownItemError,
)
from study.session.experimenter import ExperimenterActions, _reason  # noqa: F401

# Re-exported names: this module is the session engine's public import path.
from study.session.lease_keeper import LeaseKeeper  # noqa: F401
from study.session.opening import SessionOpening
from study.session.participant import ParticipantActions
from study.session.participant import goal_info as _goal_info  # noqa: F401
from study.session.plan import Plan, Step, build_plan, run_label  # noqa: F401
from study.session.sample_writer import SampleWriter  # noqa: F401
from study.session.screen import Item, Overview, Phase, Progress, Screen  # noqa: F401
from study.session.store_open import check_protocol as _check_protocol  # noqa: F401
from study.session.store_open import open_store
from study.session.trial_run import TrialFactory, TrialRun, TrialSummary  # noqa: F401
from study.session.views import LOGGER  # noqa: F401
from study.store import (  # noqa: F401
    ProtocolMismatchError,
    Store,
    Transaction,
    UnknownParticipantError,
    changed_sections,
    check_participant_id,
)


class Session(SessionOpening, ParticipantActions, ExperimenterActions):
    """A participant's session bound to this process (holds the session's lease).

    Create with ``Session.enrol`` (new participant) or ``Session.reopen`` (continue after a
    restart or crash); ``close()`` when done with it (the study session itself may go on later).
    """


__all__ = ["Session", "TrialRun", "TrialSummary", "UnknownParticipantError", "open_store"]
