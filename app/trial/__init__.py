"""Trials: one input source -> blending -> robot loop, its configuration, records and outcome.

``TrialConfig`` (validated settings) -> ``Trial(config, input_source, seed=...)`` driven by
``tick()`` (or ``run()``/``run_trial``) -> ``TickRecord`` per tick (its ``events`` are
``TrialEvent`` values), ``TrialResult`` at the end; what the ticks mean is the trial's ``Task``
(``app.trial.tasks``: the study's ``LiftTask`` by default, one task per module), what the
blender gave at the last tick its ``blend`` (a ``BlendTick``); ``save_records``/``load_records``
keep the records in a file, ``records_from_samples`` rebuilds them from a study store's samples.

Formats, each declared once: ``app.trial.events`` (event kinds and their text codec,
``encode``/``decode``) and ``app.trial.samples`` (the per-tick columns a store keeps). Videos:
``app.trial.video`` (``render_live``, ``replay``; imported on its own: it loads OpenCV).
"""

from app.trial.config import TrialConfig
from app.trial.errors import TrialConfigError, TrialError
from app.trial.events import EventKind, TrialEvent, TrialEventError
from app.trial.record_file import load_records, save_records
from app.trial.records import OUTCOMES, BlendTick, TickRecord, TrialResult
from app.trial.samples import records_from_samples
from app.trial.tasks import LiftTask, Task
from app.trial.trial import Trial, run_trial

__all__ = [
    "OUTCOMES",
    "BlendTick",
    "EventKind",
    "LiftTask",
    "Task",
    "TickRecord",
    "Trial",
    "TrialConfig",
    "TrialConfigError",
    "TrialError",
    "TrialEvent",
    "TrialEventError",
    "TrialResult",
    "load_records",
    "records_from_samples",
    "run_trial",
    "save_records",
]
