"""Trials: one input source -> blending -> robot loop, its configuration, records and outcome.

``TrialConfig`` (validated settings) -> ``Trial(config, input_source, seed=...)`` driven by
``tick()`` (or ``run()``/``run_trial``) -> ``TickRecord`` per tick, ``TrialResult`` at the end.
Videos: ``app.trial.video`` (``render_live``, ``replay``).
"""

from app.trial.config import TrialConfig
from app.trial.errors import TrialConfigError, TrialError
from app.trial.records import (
    OUTCOMES,
    TickRecord,
    TrialResult,
    load_records,
    records_from_samples,
    save_records,
)
from app.trial.trial import Trial, run_trial

__all__ = [
    "OUTCOMES",
    "TickRecord",
    "Trial",
    "TrialConfig",
    "TrialConfigError",
    "TrialError",
    "TrialResult",
    "load_records",
    "records_from_samples",
    "run_trial",
    "save_records",
]
