"""``Session``: a participant's session bound to this process, composed of small parts.

    RunState            the one owner of run state: cursor, status, paused (by what), active run
    Ledger              lease-checked transactions (restores the state when one fails)
    Steps               read-only queries over plan, state and store; the guards
    views               screen(), overview(), the experimenter actions valid now
    ParticipantActions  agree, start_trial, answer, finish, a trial that ended by itself
    ExperimenterActions start, pause, resume, redo, skip, withdraw, end

``Session`` owns the lock, the lease's heartbeat and the sample writer, takes the lock around
every part's call and tells listeners after releasing it. ``study.session`` explains the locks.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any, Self

from app.trial import Trial, TrialConfig
from study.protocol import Protocol, Texts
from study.session.closing import close_session
from study.session.experimenter_actions import ExperimenterActions
from study.session.lease_keeper import LeaseKeeper
from study.session.ledger import Ledger, SessionInfo
from study.session.opening import check_reopenable, enrol_participant
from study.session.participant_actions import ParticipantActions
from study.session.plan import Plan, build_plan
from study.session.sample_writer import DEFAULT_FLUSH_INTERVAL_S, SampleWriter, WriterStats
from study.session.screen import Overview, Phase, Screen
from study.session.state import PauseCause, RunState
from study.session.steps import Steps
from study.session.store_open import check_protocol
from study.session.trial_run import TrialFactory, TrialRun
from study.session.views import overview, screen
from study.store import Store

LOGGER = logging.getLogger("study.session")
Listener = Callable[[Screen], None]


def default_trial_factory(config: TrialConfig, input_source: Any, seed: int) -> Trial:
    """``app.trial.Trial(config, input_source, seed=seed)``, keeping no records in memory: the
    run writes each tick to the store (a long trial would otherwise grow the process)."""
    return Trial(config, input_source, seed=seed, keep_records=False)


class Session:
    """A participant's session bound to this process (holds the session's lease).

    Create with ``Session.enrol`` (new participant) or ``Session.reopen`` (continue after a
    restart or crash); ``close()`` when done with it (the study session itself may go on later).
    Every public method is thread-safe.
    """

    def __init__(
        self,
        *,
        store: Store,
        protocol: Protocol,
        participant: str,
        trial_factory: TrialFactory | None = None,
        heartbeat_s: float = 2.0,
        flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
    ) -> None:
        check_protocol(store, protocol)
        self.store = store
        self.protocol = protocol
        record = store.session(participant)
        events = store.events(session_id=record.session_id)
        self.info = SessionInfo(
            participant=participant,
            session_id=record.session_id,
            seed=record.seed,
            schedule_row=store.participant(participant).schedule_row,
            assignments=tuple(store.assignments(participant)),
            by_link=any(e.kind == "enrol" and e.detail.get("recruitment") for e in events),
        )
        self.plan: Plan = build_plan(protocol, self.info.assignments)
        self._state = RunState(status=record.status, cursor=record.cursor)
        for event in events:
            if event.kind == "skip":
                self._state.skipped.update(event.detail.get("steps", []))
        self._lock = threading.RLock()
        self._listeners: list[Listener] = []
        lease = store.acquire_lease(participant)
        self._keeper = LeaseKeeper(store, lease, interval_s=heartbeat_s)
        self._writer = SampleWriter(store, flush_interval_s=flush_interval_s)
        self._ledger = Ledger(
            store=store,
            protocol=protocol,
            info=self.info,
            state=self._state,
            lease=lease,
            keeper=self._keeper,
        )
        self._steps = Steps(
            plan=self.plan, state=self._state, protocol=protocol, store=store, ledger=self._ledger
        )
        self._participant = ParticipantActions(
            steps=self._steps,
            ledger=self._ledger,
            state=self._state,
            writer=self._writer,
            factory=trial_factory or default_trial_factory,
            run_ended=self._trial_finished,
        )
        self._experimenter = ExperimenterActions(
            steps=self._steps, ledger=self._ledger, state=self._state, writer=self._writer
        )

    # ---- opening ----------------------------------------------------------------------------------
    @classmethod
    def enrol(
        cls,
        store: Store,
        protocol: Protocol,
        participant: str,
        *,
        demographics: Mapping[str, Any] | None = None,
        seed: int = 0,
        schedule_row: int | None = None,
        recruitment: Mapping[str, str] | None = None,
        trial_factory: TrialFactory | None = None,
        heartbeat_s: float = 2.0,
        flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
    ) -> Self:
        """Enrol a new participant (pseudonymous ``participant`` ID; ``demographics`` go to their
        own table; ``recruitment``, the IDs of an online panel's link such as ``PROLIFIC_PID``,
        go to the ``enrol`` event) and open their session. The schedule row comes from ``study.schedule.next_row``
        over everyone enrolled so far unless given. Raises ``DuplicateParticipantError`` if the ID
        is taken, ``InvalidParticipantIdError`` if it is not a pseudonym, ``InvalidSeedError`` if
        ``seed`` is not in ``0..MAX_SEED`` and ``ScheduleError`` for a negative ``schedule_row``;
        nothing is written then."""
        enrol_participant(
            store,
            protocol,
            participant,
            demographics=demographics,
            seed=seed,
            schedule_row=schedule_row,
            recruitment=recruitment,
        )
        return cls(
            store=store,
            protocol=protocol,
            participant=participant,
            trial_factory=trial_factory,
            heartbeat_s=heartbeat_s,
            flush_interval_s=flush_interval_s,
        )

    @classmethod
    def reopen(
        cls,
        store: Store,
        protocol: Protocol,
        participant: str,
        *,
        trial_factory: TrialFactory | None = None,
        heartbeat_s: float = 2.0,
        flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
    ) -> Self:
        """Continue ``participant``'s session where it stopped. A trial left running by a dead
        process is marked interrupted (its samples up to the last batch kept) and will run again
        as a new attempt. Raises ``UnknownParticipantError``, ``SessionLockedError`` (a live
        process holds it), ``SessionStateError`` (the session already ended) or
        ``InvalidSeedError`` (the store holds a seed no session can run with)."""
        check_reopenable(store, protocol, participant)
        session = cls(
            store=store,
            protocol=protocol,
            participant=participant,
            trial_factory=trial_factory,
            heartbeat_s=heartbeat_s,
            flush_interval_s=flush_interval_s,
        )
        try:
            session._record_reopen()
        except BaseException:
            session.close()
            raise
        return session

    def _record_reopen(self) -> None:
        ledger = self._ledger
        with ledger.tx() as tx:
            interrupted = tx.interrupt_running_trials(self.session_id)
            detail: dict[str, Any] = {"cursor": self._state.cursor, "interrupted": interrupted}
            if ledger.lease.took_over:
                detail["took_over"] = ledger.lease.took_over
            ledger.event(tx, "reopen", detail)

    # ---- state ------------------------------------------------------------------------------------
    @property
    def participant(self) -> str:
        return self.info.participant

    @property
    def session_id(self) -> int:
        return self.info.session_id

    @property
    def seed(self) -> int:
        return self.info.seed

    @property
    def schedule_row(self) -> int:
        return self.info.schedule_row

    @property
    def status(self) -> str:
        """``enrolled``, ``running``, ``completed``, ``withdrawn`` or ``ended``."""
        return self._state.status

    @property
    def cursor(self) -> int:
        return self._state.cursor

    @property
    def finished(self) -> bool:
        return self._state.finished

    @property
    def paused(self) -> bool:
        return self._state.paused

    @property
    def paused_by(self) -> PauseCause | None:
        """Who paused the session (``None`` while it is not paused)."""
        return self._state.paused_by

    @property
    def active_run(self) -> TrialRun | None:
        """The running trial attempt, if any (for the control loop to tick)."""
        return self._state.active

    @property
    def samples_error(self) -> BaseException | None:
        """Why this session's samples are not reaching the store (a full or read-only disk:
        ``StoreWriteError``), or ``None``. The rows are held in memory and retried every batch
        period, so this turns ``None`` again by itself once the disk takes writes; a live
        server can show it to the experimenter and hold the trial until then."""
        return self._writer.error

    @property
    def sample_stats(self) -> WriterStats:
        """The sample writer's commit times (benchmarks read them)."""
        return self._writer.stats

    # ---- views ------------------------------------------------------------------------------------
    @property
    def texts(self) -> Texts:
        """The protocol's texts as this participant reads them (the online consent and
        debrief for one who came by the open link)."""
        return self._steps.texts

    def phase(self) -> Phase:
        with self._lock:
            return self._steps.phase()

    def screen(self) -> Screen:
        """What the participant should see now (no condition names anywhere)."""
        with self._lock:
            return screen(self._steps, revision=self._state.revision)

    def overview(self) -> Overview:
        """The experimenter's view: the current step's full condition and the schedule."""
        with self._lock:
            return overview(self._steps, self.info)

    def trial_config(self) -> TrialConfig:
        """The current trial step's configuration (server side; carries the condition)."""
        with self._lock:
            return self._steps.config(
                self._steps.require_phase("ready", "running", action="trial_config")
            )

    def add_listener(self, listener: Listener) -> None:
        """Call ``listener(screen)`` after every transition (from the acting thread)."""
        with self._lock:
            self._listeners.append(listener)

    def record_event(self, kind: str, detail: Mapping[str, Any] | None = None) -> None:
        """Append an event of the caller's to the session's log: the one way for a UI, server or
        simulator to log its own events (tab connected, input rejected, simulated parameters).

            session.record_event("participant_connected", {"client": 3})

        ``detail`` must be JSON-serialisable. Thread-safe. Each kind is rate-limited (10 at
        once, then 1 per second; ``study.session.event_limit``) because a client can trigger
        some at will: an event over the limit is counted instead of written, and the next one
        written carries ``"suppressed": k``; counts still pending at ``close()`` are written
        there as one ``events_suppressed`` event. The event is written in the same transaction
        that checks this process still holds the participant's lease, so a session taken over
        by another process (``SessionLockedError``) or closed (``SessionClosedError``) cannot
        add to the log; nothing is written then. Prefer this to ``store.transaction()`` +
        ``tx.event(...)``, which skips that check."""
        with self._lock:
            self._ledger.record_event(kind, detail)

    # ---- participant actions ------------------------------------------------------------------------
    def agree(self) -> Screen:
        """The participant gives consent."""
        with self._lock:
            self._participant.agree()
        return self._changed()

    def start_trial(self, *, input_source: Any) -> TrialRun:
        """Start the next attempt of the current trial step with ``input_source`` driving it."""
        with self._lock:
            run = self._participant.start_trial(input_source)
        self._changed()
        return run

    def answer(self, answers: Mapping[str, object]) -> Screen:
        """Record answers to items on the current screen (all or some of them); the session
        moves on once every item of the step is answered. Raises ``UnknownItemError`` for an
        item not pending here and ``InvalidAnswerError`` for a value off its scale; nothing is
        recorded then."""
        with self._lock:
            self._participant.answer(answers)
        return self._changed()

    def finish(self) -> Screen:
        """The participant has read the debrief: the session is completed."""
        with self._lock:
            self._participant.finish()
        return self._changed()

    def _trial_finished(self, run: TrialRun) -> None:
        """Called from the control thread when ``run``'s trial ended by itself."""
        with self._lock:
            moved_on = self._participant.trial_finished(run)
        if moved_on:
            self._changed()

    # ---- experimenter actions -----------------------------------------------------------------------
    def start(self) -> Screen:
        """Start the session (or continue it in this process after a restart)."""
        with self._lock:
            self._experimenter.start()
        return self._changed()

    def pause(self, *, cause: PauseCause = "experimenter") -> Screen:
        """Pause the session (and the running trial; paused time is not trial time).
        ``cause="tab_lost"`` when the participant's tab went away (they may resume it)."""
        with self._lock:
            self._experimenter.pause(cause)
        return self._changed()

    def resume(self) -> Screen:
        """Continue a paused session."""
        with self._lock:
            self._experimenter.resume()
        return self._changed()

    def redo(self, *, reason: str) -> Screen:
        """Run a trial again: the running attempt, or the one just completed if nothing after it
        has started or been answered. The earlier attempt is kept, marked ``redone``."""
        with self._lock:
            self._experimenter.redo(reason)
        return self._changed()

    def skip(self, *, reason: str) -> Screen:
        """Skip the current trial (with its follow-up items) or the current items."""
        with self._lock:
            self._experimenter.skip(reason)
        return self._changed()

    def withdraw(self, *, reason: str = "participant withdrew") -> Screen:
        """The participant withdraws: the session ends, everything recorded is kept."""
        with self._lock:
            self._experimenter.terminate("withdrawn", reason)
        return self._changed()

    def end(self, *, reason: str) -> Screen:
        """The experimenter ends the session early (recorded data kept)."""
        with self._lock:
            self._experimenter.terminate("ended", reason)
        return self._changed()

    # ---- release ------------------------------------------------------------------------------------
    def close(self) -> None:
        """Release this process's hold on the session (a running trial is marked interrupted).
        The session can be continued later with ``Session.reopen``. Idempotent. If the store
        refuses writes the session is still closed and the error raised afterwards
        (``study.session.closing`` says what the file holds then)."""
        with self._lock:
            close_session(
                state=self._state,
                ledger=self._ledger,
                writer=self._writer,
                keeper=self._keeper,
                stop=self._experimenter.stop,
            )

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _changed(self) -> Screen:
        with self._lock:
            self._state.revision += 1
            listeners = list(self._listeners)
        current = self.screen()
        for listener in listeners:
            try:
                listener(current)
            except Exception:  # a UI's bug must not undo or block a committed transition
                LOGGER.exception("session listener %r failed", listener)
        return current


__all__ = ["Listener", "Session", "default_trial_factory"]
