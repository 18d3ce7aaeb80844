"""The session engine: one participant's way through the study, as a state machine over the plan.

    enrol -> [waiting] -start-> consent -agree-> training runs (unassisted) -> baseline items
          -> per task in schedule order: run, items, run, items, preference -> debrief -finish-> done

The same engine serves the study server (``study.server``: participant and experimenter views in a
browser) and headless runs (``python -m study run``, simulated participants:
``study.session.headless``). Every transition is one store transaction that also appends an event,
so a killed process leaves the store at a step boundary (or inside a trial, which
``Session.reopen`` marks interrupted and runs again as a new attempt).

Participant actions: ``steps.PARTICIPANT_ACTIONS`` (per screen). Experimenter actions:
``EXPERIMENTER_ACTIONS`` (the console's buttons and the server's checks derive from it; those in
``NEEDS_REASON`` take a reason for the record).
Views: ``screen()`` (blind, for the participant's browser), ``overview()`` (experimenter).

Parts (``study.session.session`` composes them): ``state.RunState`` (the one owner of run
state: cursor, status, paused and by what, the active run), ``ledger.Ledger`` (lease-checked
transactions), ``steps.Steps`` (read-only queries and guards), ``views`` (screen, overview),
``participant`` / ``experimenter`` (the actions), ``opening`` (enrol, reopen checks),
``trial_run.TrialRun`` (one attempt, ticked by a control loop), ``sample_writer``,
``sample_committer``,
``lease_keeper``, ``event_limit``, ``plan``, ``screen``, ``errors``, ``store_open``.

Threads and locks
-----------------
Threads: viser's callback threads and the experimenter console (any action), one control loop per
running trial (``TrialRun.tick``), the live server's page and render loops, the sample
committer's (one per store) and the lease keeper's background threads. The locks of the project,
and what each guards:

- ``Session._lock`` (RLock): the ``RunState`` and every store write of the session; every
  public ``Session`` method takes it.
- ``TrialRun._lock``: one tick against pause, resume and abort of the same run.
- ``app.trial.Trial._lock`` (RLock): the trial's physics state against its pause and abort.
- ``SampleWriter._buffer_lock``: the row buffer (held for an append: microseconds);
  ``SampleCommitter._flush_lock``: one commit of a store's sample buffers at a time;
  ``sample_committer._REGISTRY_LOCK``: the committers and their writers.
- ``Store._lock`` (RLock): the main SQLite connection; ``Store._samples_lock``: the samples one.
- ``LiveSession._lock`` (RLock): the live session's current run, trial, input and scene view.
- ``LiveView._lock``: one scene frame against a preview draw or a view rebuild.
- ``LivePlots._lock``: the console's plot rows.
- ``ParticipantPage._lock`` (RLock): the tab's widgets (one screen built at a time); each screen's
  ``claimed`` lock: the first click on it wins, once.
- ``ParticipantInput._lock``, ``GizmoInput._lock``, ``KeyboardInput._lock``: the participant's
  target, held keys, grasp request and frozen flag.
- ``NeutralNames._lock``: the scene's opaque node ids.
- ``StudyServer._lock`` (RLock): the server's sessions, tabs (``ParticipantTabs``, which
  shares it) and join codes.
- ``JoinThrottle._lock``: join attempts per client and address.
- ``BlindingGuard._lock``, ``Firewall._lock``, ``Door._lock``: their counters;
  ``firewall.hooks._LOCK`` -> ``viser_door._LOCK``: installing each hook once per server.
- ``dask_engine._Bars._lock``: the progress bars of a simulated study.

Lock order: a thread holding a lock takes only locks to its right on these chains, never the
reverse, so no two threads can wait on each other:

    LiveSession._lock -> LiveView._lock
    LiveSession._lock -> ParticipantPage._lock
    LiveSession._lock -> Session._lock -> TrialRun._lock -> Trial._lock -> ParticipantInput._lock
                                                                        -> Gizmo/KeyboardInput
    TrialRun._lock -> SampleWriter._buffer_lock
    Session._lock -> SampleCommitter._flush_lock -> SampleWriter._buffer_lock
    SampleCommitter._flush_lock -> Store._samples_lock
    Session._lock -> Store._lock;  StudyServer._lock -> Store._lock (opening a session)

The control thread takes ``Session._lock`` only when its trial ends by itself, and then after
releasing ``TrialRun._lock`` (``TrialRun.tick`` calls back last); it never touches SQLite (the
sample committer's thread does). Session listeners run after ``Session._lock`` is released. The
other locks are leaves: nothing else is taken while one is held.
"""

from __future__ import annotations

from study.session.errors import (
    MAX_SEED,
    InvalidAnswerError,
    InvalidSeedError,
    MissingReasonError,
    SessionClosedError,
    SessionError,
    SessionStateError,
    UnknownItemError,
)
from study.session.experimenter_actions import check_reason
from study.session.screen import Overview, Progress, Screen
from study.session.session import Session
from study.session.state import FINAL_STATUSES, PauseCause
from study.session.store_open import open_store
from study.session.trial_run import TrialRun, TrialSummary
from study.session.views import EXPERIMENTER_ACTIONS, NEEDS_REASON

__all__ = [
    "EXPERIMENTER_ACTIONS",
    "FINAL_STATUSES",
    "MAX_SEED",
    "NEEDS_REASON",
    "InvalidAnswerError",
    "InvalidSeedError",
    "MissingReasonError",
    "Overview",
    "PauseCause",
    "Progress",
    "Screen",
    "Session",
    "SessionClosedError",
    "SessionError",
    "SessionStateError",
    "TrialRun",
    "TrialSummary",
    "UnknownItemError",
    "check_reason",
    "open_store",
]
