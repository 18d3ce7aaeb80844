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
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from study.lease_keeper import LeaseKeeper
from study.plan import Plan, Step, build_plan, run_label
from study.protocol import AnswerError
from study.sample_writer import SampleWriter
from study.schedule import Design, Enrollment, next_row
from study.screen import Item, Overview, Phase, Progress, Screen
from study.session_errors import (
    InvalidAnswerError,
    MissingReasonError,
    SessionClosedError,
    SessionError,
    SessionStateError,
    UnknownItemError,
)
from study.store import (
    ProtocolMismatchError,
    Store,
    Transaction,
    UnknownParticipantError,
    changed_sections,
    check_participant_id,
)
from study.trial_run import TrialFactory, TrialRun, TrialSummary

if TYPE_CHECKING:
    from app.trial import TrialConfig
    from study.protocol import Protocol

LOGGER = logging.getLogger("study.session")
FINAL_STATUSES = ("completed", "withdrawn", "ended")
Listener = Callable[[Screen], None]


def open_store(path: str | Path, protocol: Protocol, *, synchronous: str = "FULL") -> Store:
    """Open (or create) the store at ``path`` for ``protocol``; a new store keeps the protocol's
    full text, so export and analysis can rebuild it (``study.protocol.protocol_from_store``).

    Raises ``ProtocolMismatchError`` (naming both content hashes and the changed sections) if
    the store was started with another protocol: continue with the original file, or use a new
    path for the edited protocol."""
    return Store.open(
        path,
        protocol_id=protocol.id,
        protocol_hash=protocol.content_hash,
        protocol_version=protocol.study.version,
        protocol_text=protocol.source or None,
        synchronous=synchronous,
    )


def default_trial_factory(config: TrialConfig, input_source: Any, seed: int) -> Any:
    """``app.trial.Trial(config, input_source, seed=seed)`` (imported on first use)."""
    from app.trial import Trial  # type: ignore[attr-defined]

    return Trial(config, input_source, seed=seed)


def trial_seed(session_seed: int, step: int, attempt: int) -> int:
    """A trial attempt's seed, fixed by the session seed, the step and the attempt number."""
    return int(np.random.SeedSequence([session_seed, step, attempt]).generate_state(1)[0])


class Session:
    """A participant's session bound to this process (holds the session's lease).

    Create with ``Session.enrol`` (new participant) or ``Session.reopen`` (continue after a
    restart or crash); ``close()`` when done with it (the study session itself may go on later).
    """

    def __init__(
        self,
        *,
        store: Store,
        protocol: Protocol,
        participant: str,
        trial_factory: TrialFactory | None,
        heartbeat_s: float,
        flush_interval_s: float,
    ) -> None:
        _check_protocol(store, protocol)
        self.store = store
        self.protocol = protocol
        self.participant = participant
        self._factory = trial_factory or default_trial_factory
        self._lock = threading.RLock()
        self._listeners: list[Listener] = []
        record = store.session(participant)
        self.session_id = record.session_id
        self.seed = record.seed
        self._status = record.status
        self._cursor = record.cursor
        self.schedule_row = store.participant(participant).schedule_row
        self._assignments = store.assignments(participant)
        self.plan: Plan = build_plan(protocol, self._assignments)
        self._skipped: set[int] = set()
        for event in store.events(session_id=self.session_id):
            if event.kind == "skip":
                self._skipped.update(event.detail.get("steps", []))
        self._lease = store.acquire_lease(participant)
        self._keeper = LeaseKeeper(store, self._lease, interval_s=heartbeat_s)
        self._writer = SampleWriter(store, flush_interval_s=flush_interval_s)
        self._started = False
        self._paused = False
        self._closed = False
        self._active: TrialRun | None = None
        self._revision = 0

    # ---- construction ---------------------------------------------------------------------------
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
        trial_factory: TrialFactory | None = None,
        heartbeat_s: float = 2.0,
        flush_interval_s: float = 0.1,
    ) -> Session:
        """Enrol a new participant (pseudonymous ``participant`` ID; ``demographics`` go to their
        own table) and open their session. The schedule row comes from ``study.schedule.next_row``
        over everyone enrolled so far unless given. Raises ``DuplicateParticipantError`` if the ID
        is taken, ``InvalidParticipantIdError`` if it is not a pseudonym."""
        check_participant_id(participant)
        _check_protocol(store, protocol)
        design = Design.from_protocol(protocol)
        with store.transaction() as tx:
            history = tx.enrolment_history()
            if schedule_row is None:
                schedule_row = next_row(
                    Enrollment(p, withdrawn=status == "withdrawn", row=row)
                    for p, row, status in history
                )
            rows = [
                (t.position, t.task, run_label(t.run), t.mode)
                for t in design.row_trials(schedule_row, participant=participant)
            ]
            session_id = tx.enrol(
                participant,
                schedule_row=schedule_row,
                assignments=rows,
                seed=seed,
                demographics=demographics,
            )
            tx.event(
                session_id,
                participant,
                "enrol",
                {"schedule_row": schedule_row, "seed": seed, "demographics": bool(demographics)},
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
        flush_interval_s: float = 0.1,
    ) -> Session:
        """Continue ``participant``'s session where it stopped. A trial left running by a dead
        process is marked interrupted (its samples up to the last batch kept) and will run again
        as a new attempt. Raises ``UnknownParticipantError``, ``SessionLockedError`` (a live
        process holds it) or ``SessionStateError`` (the session already ended)."""
        _check_protocol(store, protocol)
        record = store.session(participant)
        if record.status in FINAL_STATUSES:
            raise SessionStateError(
                f"participant {participant}'s session is already {record.status}; there is "
                "nothing to resume (enrol a new participant ID for a new session)"
            )
        session = cls(
            store=store,
            protocol=protocol,
            participant=participant,
            trial_factory=trial_factory,
            heartbeat_s=heartbeat_s,
            flush_interval_s=flush_interval_s,
        )
        try:
            with session._tx() as tx:
                interrupted = tx.interrupt_running_trials(session.session_id)
                detail: dict[str, Any] = {"cursor": session._cursor, "interrupted": interrupted}
                if session._lease.took_over:
                    detail["took_over"] = session._lease.took_over
                tx.event(session.session_id, participant, "reopen", detail)
        except BaseException:
            session.close()
            raise
        return session

    # ---- views ------------------------------------------------------------------------------------
    @property
    def status(self) -> str:
        """``enrolled``, ``running``, ``completed``, ``withdrawn`` or ``ended``."""
        return self._status

    @property
    def cursor(self) -> int:
        return self._cursor

    @property
    def active_run(self) -> TrialRun | None:
        """The running trial attempt, if any (for the control loop to tick)."""
        return self._active

    @property
    def finished(self) -> bool:
        return self._status in FINAL_STATUSES

    def phase(self) -> Phase:
        with self._lock:
            return self._phase()

    def screen(self) -> Screen:
        """What the participant should see now (no condition names anywhere)."""
        with self._lock:
            phase = self._phase()
            texts = self.protocol.texts
            step = self._step()
            progress = Progress(self._trial_progress(), self.plan.n_trials)
            items: tuple[Item, ...] = ()
            actions: tuple[str, ...] = ()
            if phase == "waiting":
                title, text = "Welcome", texts.instructions["welcome"]
            elif phase == "consent":
                title, text, actions = "Consent", texts.consent, ("agree",)
            elif phase in ("ready", "running") and step is not None:
                if step.phase == "training":
                    title = f"Practice run {step.trial_number} of {self.protocol.training.runs}"
                    text = self.protocol.describe_training()
                else:
                    title = progress.text
                    text = self.protocol.describe_trial(step.task or "")
                actions = ("start_trial",) if phase == "ready" else ()
            elif phase == "questions" and step is not None:
                pending = self._pending_items(step)
                key = "preference" if step.questionnaire == "after_task" else "rating"
                title = "Questions"
                text = texts.instructions.get(key, texts.instructions["rating"])
                items = tuple(Item(i.id, i.prompt, i.scale.anchors) for i in pending)
                actions = ("answer",)
            elif phase == "debrief":
                title, text, actions = "Thank you", texts.debrief, ("finish",)
            else:
                title, text = "Done", texts.debrief if self._status == "completed" else ""
            if self._paused:
                text = texts.instructions.get("pause", "The session is paused.")
                actions = ()
            return Screen(
                phase=phase,
                title=title,
                text=text.strip(),
                progress=progress,
                items=items,
                actions=actions,
                paused=self._paused,
                questionnaire=step.questionnaire if phase == "questions" and step else None,
                revision=self._revision,
            )

    def overview(self) -> Overview:
        """The experimenter's view: the current step's full condition and the schedule."""
        with self._lock:
            step = self._step()
            run = self._active
            trials = self.store.trials(session_id=self.session_id)
            attempt = None
            if step is not None and step.kind == "trial":
                attempt = run.attempt if run else self._next_attempt(step.index)
            task = self.protocol.task(step.task) if step is not None and step.task else None
            return Overview(
                participant=self.participant,
                session_id=self.session_id,
                status=self._status,
                phase=self._phase(),
                paused=self._paused,
                step=self._cursor,
                steps=len(self.plan),
                step_kind=step.kind if step else None,
                training_or_task=step.phase if step else None,
                task=step.task if step else None,
                difficulty=task.difficulty if task else None,
                correctness=task.correctness if task else None,
                mode=step.mode if step else None,
                run=step.run if step else None,
                attempt=attempt,
                trial_id=run.trial_id if run else None,
                trials_completed=sum(t.status == "completed" for t in trials),
                ratings=len(self.store.ratings(session_id=self.session_id)),
                schedule_row=self.schedule_row,
                schedule=tuple((a.position, a.task, a.run, a.mode) for a in self._assignments),
                skipped_steps=tuple(sorted(self._skipped)),
                experimenter_actions=self._experimenter_actions(),
            )

    def trial_config(self) -> TrialConfig:
        """The current trial step's configuration (server side; carries the condition)."""
        with self._lock:
            step = self._require_phase("ready", "running", action="trial_config")
            return self._config(step)

    def record_event(self, kind: str, detail: Mapping[str, Any] | None = None) -> None:
        """Append an event of the caller's to the session's log: the one way for a UI, server or
        simulator to log its own events (tab connected, input rejected, simulated parameters).

            session.record_event("participant_connected", {"client": 3})

        ``detail`` must be JSON-serialisable. Thread-safe. The event is written in the same
        transaction that checks this process still holds the participant's lease, so a session
        taken over by another process (``SessionLockedError``) or closed
        (``SessionClosedError``) cannot add to the log; nothing is written then. Prefer this to
        ``store.transaction()`` + ``tx.event(...)``, which skips that check."""
        if not isinstance(kind, str) or not kind:
            raise SessionError("an event needs a kind (a short name such as 'tab_connected')")
        detail = dict(detail or {})
        try:
            json.dumps(detail)
        except (TypeError, ValueError) as exc:
            raise SessionError(
                f"event {kind!r}: detail must be JSON-serialisable (str, numbers, lists, dicts): "
                f"{exc}; convert arrays with .tolist()"
            ) from None
        with self._lock:
            self._require_open()
            with self._tx() as tx:
                tx.event(self.session_id, self.participant, kind, detail)

    def add_listener(self, listener: Listener) -> None:
        """Call ``listener(screen)`` after every transition (from the acting thread)."""
        with self._lock:
            self._listeners.append(listener)

    # ---- participant actions ----------------------------------------------------------------------
    def agree(self) -> Screen:
        """The participant gives consent."""
        with self._lock:
            self._require_phase("consent", action="agree")
            self._advance("consent", {})
        return self._changed()

    def start_trial(self, *, input_source: Any) -> TrialRun:
        """Start the next attempt of the current trial step with ``input_source`` driving it."""
        with self._lock:
            step = self._require_phase("ready", action="start_trial")
            attempt = self._next_attempt(step.index)
            seed = trial_seed(self.seed, step.index, attempt)
            config = self._config(step)
            trial = self._factory(config, input_source, seed)
            names, positions, target = _goal_info(trial, config)
            with self._tx() as tx:
                task = self.protocol.task(step.task) if step.task else None
                trial_id = tx.insert_trial(
                    session_id=self.session_id,
                    participant=self.participant,
                    step=step.index,
                    trial_number=step.trial_number,
                    phase=step.phase,
                    position=step.position,
                    task=step.task,
                    difficulty=task.difficulty if task else None,
                    correctness=task.correctness if task else None,
                    mode=step.mode,
                    run=step.run,
                    attempt=attempt,
                    seed=seed,
                    goal_names=names,
                    goal_positions=positions,
                    target=target,
                )
                tx.event(
                    self.session_id,
                    self.participant,
                    "trial_start",
                    {"trial_id": trial_id, "step": step.index, "attempt": attempt, "seed": seed},
                )
            run = TrialRun(
                trial=trial,
                trial_id=trial_id,
                step=step.index,
                attempt=attempt,
                seed=seed,
                config=config,
                writer=self._writer,
                on_finished=self._trial_finished,
            )
            self._active = run
        self._changed()
        return run

    def answer(self, answers: Mapping[str, object]) -> Screen:
        """Record answers to items on the current screen (all or some of them); the session
        moves on once every item of the step is answered. Raises ``UnknownItemError`` for an
        item not pending here and ``InvalidAnswerError`` for a value off its scale; nothing is
        recorded then."""
        with self._lock:
            step = self._require_phase("questions", action="answer")
            pending = {i.id: i for i in self._pending_items(step)}
            if not answers:
                raise InvalidAnswerError(f"no answers given; pending items: {', '.join(pending)}")
            values: dict[str, int] = {}
            for item_id, value in answers.items():
                if item_id not in pending:
                    asked = {i.id for i in step.items}
                    why = "was already answered" if item_id in asked else "is not asked here"
                    raise UnknownItemError(
                        f"item {item_id!r} {why}; pending items: {', '.join(pending) or 'none'}"
                    )
                try:
                    values[item_id] = pending[item_id].check(value)
                except AnswerError as exc:
                    raise InvalidAnswerError(str(exc)) from exc
            trial_id = self._rated_trial(step)
            done = len(values) == len(pending)
            with self._tx() as tx:
                for item_id, value in values.items():
                    tx.add_rating(
                        session_id=self.session_id,
                        participant=self.participant,
                        step=step.index,
                        phase=step.phase,
                        task=step.task,
                        mode=step.mode,
                        run=step.run,
                        trial_id=trial_id,
                        item=item_id,
                        value=value,
                    )
                detail = {"step": step.index, "items": sorted(values), "trial_id": trial_id}
                tx.event(self.session_id, self.participant, "answer", detail)
                if done:
                    self._move(tx, self._next_step(step.index))
        return self._changed()

    def finish(self) -> Screen:
        """The participant has read the debrief: the session is completed."""
        with self._lock:
            self._require_phase("debrief", action="finish")
            with self._tx() as tx:
                tx.update_session(self.session_id, cursor=len(self.plan), status="completed")
                tx.event(self.session_id, self.participant, "finish", {"cursor": len(self.plan)})
            self._cursor, self._status = len(self.plan), "completed"
        return self._changed()

    # ---- experimenter actions ----------------------------------------------------------------------
    def start(self) -> Screen:
        """Start the session (or continue it in this process after a restart)."""
        with self._lock:
            self._require_phase("waiting", action="start")
            with self._tx() as tx:
                tx.update_session(self.session_id, status="running")
                tx.event(self.session_id, self.participant, "start", {"cursor": self._cursor})
            self._status, self._started = "running", True
        return self._changed()

    def pause(self) -> Screen:
        """Pause the session (and the running trial; paused time is not trial time)."""
        with self._lock:
            self._require_live("pause")
            if self._paused:
                raise SessionStateError("the session is already paused; resume() continues it")
            with self._tx() as tx:
                tx.event(self.session_id, self.participant, "pause", self._where())
            if self._active:
                self._active._pause()
            self._paused = True
        return self._changed()

    def resume(self) -> Screen:
        """Continue a paused session."""
        with self._lock:
            self._require_live("resume")
            if not self._paused:
                raise SessionStateError("the session is not paused; nothing to resume")
            with self._tx() as tx:
                tx.event(self.session_id, self.participant, "resume", self._where())
            if self._active:
                self._active._resume()
            self._paused = False
        return self._changed()

    def redo(self, *, reason: str) -> Screen:
        """Run a trial again: the running attempt, or the one just completed if nothing after it
        has started or been answered. The earlier attempt is kept, marked ``redone``."""
        reason = _reason(reason, "redo")
        with self._lock:
            self._require_live("redo")
            run, step = self._active, self._step()
            if run is None:
                target, trial_id = self._redo_target(step)
            self._stop(run)
            with self._tx() as tx:
                if run is not None:
                    self._record_abort(tx, run, status="redone", note=f"redone: {reason}")
                    target, trial_id = run.step, run.trial_id
                else:
                    tx.set_trial_status(trial_id, "redone", note=f"redone: {reason}")
                    tx.update_session(self.session_id, cursor=target)
                tx.event(
                    self.session_id,
                    self.participant,
                    "redo",
                    {"step": target, "trial_id": trial_id, "reason": reason, "cursor": target},
                )
            self._cursor = target
        return self._changed()

    def skip(self, *, reason: str) -> Screen:
        """Skip the current trial (with its follow-up items) or the current items."""
        reason = _reason(reason, "skip")
        with self._lock:
            self._require_live("skip")
            step = self._step()
            if step is None or step.kind not in ("trial", "questions"):
                raise SessionStateError(
                    f"skip applies to trials and questions, not to the {self._phase()} screen"
                )
            skipped = [step.index]
            self._stop(self._active)
            with self._tx() as tx:
                trial_id = None
                if step.kind == "trial":
                    skipped += [s for s in self.plan.dependents(step.index) if s not in skipped]
                    if self._active is not None:
                        trial_id = self._active.trial_id
                        self._record_abort(
                            tx, self._active, status="skipped", note=f"skipped: {reason}"
                        )
                    else:
                        trial_id = self._skipped_trial_row(tx, step, reason)
                self._skipped.update(skipped)
                nxt = self._next_step(step.index)
                tx.event(
                    self.session_id,
                    self.participant,
                    "skip",
                    {"steps": skipped, "trial_id": trial_id, "reason": reason, "cursor": nxt},
                )
                self._move(tx, nxt)
        return self._changed()

    def withdraw(self, *, reason: str = "participant withdrew") -> Screen:
        """The participant withdraws: the session ends, everything recorded is kept."""
        return self._terminate("withdrawn", _reason(reason, "withdraw"))

    def end(self, *, reason: str) -> Screen:
        """The experimenter ends the session early (recorded data kept)."""
        return self._terminate("ended", _reason(reason, "end"))

    def close(self) -> None:
        """Release this process's hold on the session (a running trial is marked interrupted).
        The session can be continued later with ``Session.reopen``. Idempotent."""
        with self._lock:
            if self._closed:
                return
            try:
                if not self._keeper.lost and self._status not in FINAL_STATUSES:
                    where, run = self._where(), self._active
                    self._stop(run)
                    with self._tx() as tx:
                        if run is not None:
                            self._record_abort(tx, run, status="interrupted", note="session closed")
                        tx.event(self.session_id, self.participant, "close", where)
            finally:
                self._closed = True
                try:
                    self._writer.close()
                finally:
                    self._keeper.stop(release=True)

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- internals (called with self._lock held) ---------------------------------------------------
    def _phase(self) -> Phase:
        if self._status in FINAL_STATUSES:
            return "done"
        if not self._started:
            return "waiting"
        step = self._step()
        if step is None:
            return "done"
        if step.kind == "trial":
            return "running" if self._active is not None else "ready"
        return step.kind  # consent, questions, debrief

    def _step(self) -> Step | None:
        return self.plan[self._cursor] if self._cursor < len(self.plan) else None

    def _require_open(self) -> None:
        if self._closed:
            raise SessionClosedError(
                f"this session object for {self.participant} is closed; reopen the session"
            )
        if self._keeper.lost:
            raise SessionClosedError(
                f"participant {self.participant}'s session was taken over by another process"
            )

    def _require_live(self, action: str) -> None:
        self._require_open()
        phase = self._phase()
        if phase in ("waiting", "done"):
            raise SessionStateError(
                f"cannot {action}: the session is {self._status if phase == 'done' else phase}"
                f"{'' if phase == 'done' else ' (call start() first)'}"
            )

    def _require_phase(self, *phases: Phase, action: str) -> Step:
        self._require_open()
        phase = self._phase()
        if phase not in phases:
            valid = ", ".join(self._participant_actions(phase)) or "none"
            raise SessionStateError(
                f"cannot {action} on the {phase} screen (status {self._status}); "
                f"participant actions valid now: {valid}"
            )
        if self._paused and action != "trial_config":
            raise SessionStateError(f"cannot {action}: the session is paused (resume() first)")
        step = self._step()
        assert step is not None or phase == "waiting"
        return step  # type: ignore[return-value]

    def _participant_actions(self, phase: Phase) -> tuple[str, ...]:
        return {
            "consent": ("agree",),
            "ready": ("start_trial",),
            "questions": ("answer",),
            "debrief": ("finish",),
        }.get(phase, ())

    def _experimenter_actions(self) -> tuple[str, ...]:
        phase = self._phase()
        if phase == "done":
            return ()
        if phase == "waiting":
            return ("start", "withdraw", "end")
        actions = ["resume" if self._paused else "pause", "withdraw", "end"]
        step = self._step()
        if step is not None and step.kind in ("trial", "questions"):
            actions.append("skip")
        try:
            if self._active is not None or self._redo_target(step):
                actions.append("redo")
        except SessionStateError:
            pass
        return tuple(actions)

    @contextmanager
    def _tx(self) -> Iterator[Transaction]:
        """A store transaction that first checks this process still holds the lease; if it
        fails, the in-memory cursor and skipped steps are restored with the rolled-back file."""
        cursor, skipped = self._cursor, set(self._skipped)
        try:
            with self.store.transaction() as tx:
                tx.require_lease(self._lease)
                yield tx
        except BaseException:
            self._cursor, self._skipped = cursor, skipped
            raise

    def _changed(self) -> Screen:
        with self._lock:
            self._revision += 1
            listeners = list(self._listeners)
        screen = self.screen()
        for listener in listeners:
            try:
                listener(screen)
            except Exception:  # a UI's bug must not undo or block a committed transition
                LOGGER.exception("session listener %r failed", listener)
        return screen

    def _where(self) -> dict[str, Any]:
        run = self._active
        return {"cursor": self._cursor, "trial_id": run.trial_id if run else None}

    def _advance(self, kind: str, detail: dict[str, Any]) -> None:
        nxt = self._next_step(self._cursor)
        with self._tx() as tx:
            tx.event(self.session_id, self.participant, kind, {**detail, "cursor": nxt})
            self._move(tx, nxt)

    def _move(self, tx: Transaction, cursor: int) -> None:
        tx.update_session(self.session_id, cursor=cursor)
        self._cursor = cursor

    def _next_step(self, index: int) -> int:
        nxt = index + 1
        while nxt < len(self.plan) - 1 and nxt in self._skipped:
            nxt += 1
        return nxt

    def _trial_progress(self) -> int:
        """The trial number shown: the current trial step's, else the last one passed."""
        done = [s.trial_number for s in self.plan.steps[: self._cursor + 1] if s.trial_number]
        return max(done, default=0)

    def _next_attempt(self, step: int) -> int:
        trials = self.store.trials(session_id=self.session_id)
        attempts = [t.attempt for t in trials if t.step == step]
        return max(attempts, default=0) + 1

    def _config(self, step: Step) -> TrialConfig:
        if step.phase == "training":
            return self.protocol.training_config()
        return self.protocol.trial_config(step.task or "", step.mode or "")

    def _pending_items(self, step: Step) -> list[Any]:
        answered = {
            r.item for r in self.store.ratings(session_id=self.session_id) if r.step == step.index
        }
        return [i for i in step.items if i.id not in answered]

    def _rated_trial(self, step: Step) -> int | None:
        """The completed trial attempt an after-run item is about (``None`` for other items)."""
        if step.rates_step is None:
            return None
        completed = [
            t.trial_id
            for t in self.store.trials(session_id=self.session_id)
            if t.step == step.rates_step and t.status == "completed"
        ]
        return completed[-1] if completed else None

    def _redo_target(self, step: Step | None) -> tuple[int, int]:
        """The completed trial just before the cursor that ``redo`` may run again."""
        prev = self._cursor - 1
        if prev < 0 or self.plan[prev].kind != "trial" or prev in self._skipped:
            raise SessionStateError(
                "nothing to redo: no trial is running and the previous step is not a completed "
                "trial"
            )
        trials = self.store.trials(session_id=self.session_id)
        if any(t.step == self._cursor for t in trials) or (
            step is not None
            and step.kind == "questions"
            and self._pending_items(step) != list(step.items)
        ):
            raise SessionStateError(
                "cannot redo the previous trial: the step after it has already started or been "
                "answered"
            )
        done = [t.trial_id for t in trials if t.step == prev and t.status == "completed"]
        if not done:
            raise SessionStateError("nothing to redo: the previous trial has no completed attempt")
        return prev, done[-1]

    def _skipped_trial_row(self, tx: Transaction, step: Step, reason: str) -> int:
        task = self.protocol.task(step.task) if step.task else None
        config = self._config(step)
        trial_id = tx.insert_trial(
            session_id=self.session_id,
            participant=self.participant,
            step=step.index,
            trial_number=step.trial_number,
            phase=step.phase,
            position=step.position,
            task=step.task,
            difficulty=task.difficulty if task else None,
            correctness=task.correctness if task else None,
            mode=step.mode,
            run=step.run,
            attempt=self._next_attempt(step.index),
            seed=0,
            goal_names=list(config.scene.object_names),
            goal_positions=[list(o.position) for o in config.scene.objects],
            target=config.scene.target,
            status="skipped",
            note=f"skipped: {reason}",
        )
        tx.end_trial(
            trial_id, status="skipped", outcome=None, success=None, duration_s=None, ticks=0
        )
        return trial_id

    def _stop(self, run: TrialRun | None) -> None:
        """Stop ``run`` (no further ticks) and commit its samples; call before the transaction
        that records how it ended (``_record_abort``)."""
        if run is not None:
            run._finish(None)
            self._writer.flush()

    def _record_abort(self, tx: Transaction, run: TrialRun, *, status: str, note: str) -> None:
        """Record the stopped ``run`` with ``status`` (outcome ``aborted``)."""
        tx.end_trial(
            run.trial_id,
            status=status,
            outcome="aborted",
            success=False,
            duration_s=run.duration_s(),
            ticks=run.ticks,
            note=note,
        )
        self._active = None

    def _trial_finished(self, run: TrialRun) -> None:
        """Called from the control thread when ``run``'s trial ended by itself."""
        with self._lock:
            if self._active is not run or self._closed:
                return  # aborted meanwhile by redo/skip/withdraw/end/close
            # If a commit below fails the run stays active and the next tick() retries.
            self._writer.flush()
            outcome = str(run.trial.outcome or "timeout")
            success = bool(getattr(run.trial, "success", outcome == "success"))
            summary = TrialSummary(run.trial_id, outcome, success, run.duration_s(), run.ticks)
            nxt = self._next_step(run.step)
            with self._tx() as tx:
                tx.end_trial(
                    run.trial_id,
                    status="completed",
                    outcome=outcome,
                    success=success,
                    duration_s=summary.duration_s,
                    ticks=summary.ticks,
                )
                tx.event(
                    self.session_id,
                    self.participant,
                    "trial_end",
                    {"trial_id": run.trial_id, "outcome": outcome, "cursor": nxt},
                )
                self._move(tx, nxt)
            run._finish(summary)
            self._active = None
        self._changed()

    def _terminate(self, status: str, reason: str) -> Screen:
        with self._lock:
            self._require_open()
            if self._status in FINAL_STATUSES:
                raise SessionStateError(f"the session is already {self._status}")
            self._stop(self._active)
            with self._tx() as tx:
                if self._active is not None:
                    self._record_abort(
                        tx, self._active, status="interrupted", note=f"{status}: {reason}"
                    )
                tx.update_session(self.session_id, status=status)
                tx.event(
                    self.session_id,
                    self.participant,
                    "withdraw" if status == "withdrawn" else "end",
                    {"reason": reason, "cursor": self._cursor},
                )
            self._status, self._paused = status, False
        return self._changed()


def _check_protocol(store: Store, protocol: Protocol) -> None:
    meta = store.meta
    if meta.protocol_hash != protocol.content_hash or meta.protocol_id != protocol.id:
        changed = changed_sections(store.protocol_text(), protocol.source or None)
        raise ProtocolMismatchError(
            f"store {store.path} was written by protocol {meta.protocol_id!r} version "
            f"{meta.protocol_version or '?'} (content hash {meta.protocol_hash}), not by "
            f"{protocol.id!r} version {protocol.study.version} (content hash "
            f"{protocol.content_hash}){f'; changed: {changed}' if changed else ''}; use the "
            "protocol the study started with (study.protocol.protocol_from_store rebuilds it), "
            "or a new store for the edited protocol (data untouched)"
        )


def _reason(reason: str, action: str) -> str:
    if not isinstance(reason, str) or not reason.strip():
        raise MissingReasonError(f"{action} needs a reason for the record (e.g. reason='...')")
    return reason.strip()


def _goal_info(trial: Any, config: TrialConfig) -> tuple[list[str], list[list[float]], str]:
    """Goal names, positions (the trial's grasp points, else the objects') and the target."""
    goals = getattr(getattr(trial, "scene", None), "goals", None)
    if goals is not None:
        names = [str(n) for n in goals.names]
        positions = np.asarray(goals.positions, dtype=float).tolist()
    else:
        names = list(config.scene.object_names)
        positions = [list(map(float, o.position)) for o in config.scene.objects]
    return names, positions, config.scene.target


__all__ = ["Session", "TrialRun", "TrialSummary", "UnknownParticipantError", "open_store"]
