"""A store filled through the session engine for the export tests (every table has rows)."""

from __future__ import annotations

import json
from pathlib import Path

from study.retention import record_retention
from study.schedule import Design
from study.session.plan import run_label
from study.store import SAMPLE_COLUMNS, Store

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT / "protocols" / "dragan2013.toml"


def sample_row(trial_id: int, tick: int, predicted: int, probs: list[float]) -> list:
    values = {c: 0.0 for c in SAMPLE_COLUMNS}
    values.update(
        trial_id=trial_id,
        tick=tick,
        t=tick / 100,
        alpha=0.25,
        confidence=0.5,
        predicted=predicted,
        probabilities=json.dumps(probs),
        target_x=0.4 + tick / 1000,
        events=json.dumps(["grasp"] if tick == 2 else []),
    )
    values["q3"] = 0.1 * tick
    return [values[c] for c in SAMPLE_COLUMNS]


def build_store(path: Path, protocol) -> dict:
    """P01: training, one task done twice (a redo first), ratings, preference, agrees to keep
    the data; P02 withdrew, and agreed in person that their run is kept."""
    design = Design.from_protocol(protocol)
    store = Store.open(
        path,
        protocol_id=protocol.id,
        protocol_hash=protocol.content_hash,
        protocol_version=protocol.study.version,
    )
    ids: dict = {}
    with store:
        with store.transaction() as tx:
            trials = design.row_trials(0, participant="P01")
            sid = tx.enrol(
                "P01",
                schedule_row=0,
                seed=1,
                assignments=[(t.position, t.task, run_label(t.run), t.mode) for t in trials],
            )
            tx.event(sid, "P01", "consent", {"agreed": True})
        training_scene = protocol.scenes[protocol.training.scene]
        step = 1
        for duration in (30.0, 40.0, 50.0):
            with store.transaction() as tx:
                tid = tx.insert_trial(
                    session_id=sid,
                    participant="P01",
                    step=step,
                    trial_number=step,
                    phase="training",
                    position=None,
                    task=None,
                    difficulty=None,
                    correctness=None,
                    mode="none",
                    run=None,
                    attempt=1,
                    seed=step,
                    goal_names=list(training_scene.object_names),
                    goal_positions=[list(o.position) for o in training_scene.objects],
                    target=training_scene.target,
                )
                tx.end_trial(
                    tid,
                    status="completed",
                    outcome="success",
                    success=True,
                    duration_s=duration,
                    ticks=0,
                )
            step += 1
        with store.transaction() as tx:
            for item, value in (("helpful", 2), ("matched", 3), ("teammate", 4)):
                tx.add_rating(
                    session_id=sid,
                    participant="P01",
                    step=step,
                    phase="training",
                    task=None,
                    mode="none",
                    run=None,
                    trial_id=None,
                    item=item,
                    value=value,
                )
        step += 1
        task = trials[0].task
        scene = protocol.scene_for(task)
        spec = protocol.task(task)
        run_ids = []
        for t, attempts in ((trials[0], ("redone", "completed")), (trials[1], ("completed",))):
            for attempt, status in enumerate(attempts, start=1):
                with store.transaction() as tx:
                    tid = tx.insert_trial(
                        session_id=sid,
                        participant="P01",
                        step=step,
                        trial_number=step,
                        phase="task",
                        position=t.position,
                        task=task,
                        difficulty=spec.difficulty,
                        correctness=spec.correctness,
                        mode=t.mode,
                        run=run_label(t.run),
                        attempt=attempt,
                        seed=7,
                        goal_names=list(scene.object_names),
                        goal_positions=[list(o.position) for o in scene.objects],
                        target=scene.target,
                    )
                    tx.end_trial(
                        tid,
                        status=status,
                        outcome="success" if status == "completed" else "aborted",
                        success=status == "completed",
                        duration_s=20.0 + 5 * t.run,
                        ticks=3,
                    )
                store.insert_samples([sample_row(tid, k, k % 2, [0.7, 0.3]) for k in range(3)])
            run_ids.append(tid)
            with store.transaction() as tx:
                for item, value in (("helpful", 5 + t.run), ("matched", 4), ("teammate", 3)):
                    tx.add_rating(
                        session_id=sid,
                        participant="P01",
                        step=step + 1,
                        phase="task",
                        task=task,
                        mode=t.mode,
                        run=run_label(t.run),
                        trial_id=tid,
                        item=item,
                        value=value,
                    )
            step += 2
        with store.transaction() as tx:
            tx.add_rating(
                session_id=sid,
                participant="P01",
                step=step,
                phase="task",
                task=task,
                mode=None,
                run=None,
                trial_id=None,
                item="preference",
                value=2,
            )
        with store.transaction() as tx:
            sid2 = tx.enrol(
                "P02",
                schedule_row=1,
                seed=2,
                assignments=[
                    (t.position, t.task, run_label(t.run), t.mode)
                    for t in design.row_trials(1, participant="P02")
                ],
            )
            tid = tx.insert_trial(
                session_id=sid2,
                participant="P02",
                step=1,
                trial_number=1,
                phase="training",
                position=None,
                task=None,
                difficulty=None,
                correctness=None,
                mode="none",
                run=None,
                attempt=1,
                seed=3,
                goal_names=list(training_scene.object_names),
                goal_positions=[list(o.position) for o in training_scene.objects],
                target=training_scene.target,
            )
            tx.set_trial_status(tid, "interrupted", note="withdrew")
            tx.update_session(sid2, status="withdrawn")
            tx.event(sid2, "P02", "withdraw", {"reason": "felt unwell"})
        with store.transaction() as tx:
            keep = protocol.questionnaire.retention
            tx.add_answer(
                session_id=sid,
                participant="P01",
                step=step + 1,
                questionnaire="closing",
                item=keep.id,
                kind=keep.kind,
                value=keep.keep,
            )
        record_retention(store, protocol, "P02", keep=True)
        ids.update(
            task=task, first_mode=trials[0].mode, second_mode=trials[1].mode, run_ids=run_ids
        )
    return ids
