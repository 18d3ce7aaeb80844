"""Trials: one input source -> blending -> robot loop, its configuration, records and outcome."""

from app.trial.config import TrialConfig
from app.trial.errors import TrialConfigError, TrialError
from app.trial.records import OUTCOMES, TickRecord, TrialResult
from app.trial.trial import Trial, run_trial

__all__ = [
    "OUTCOMES",
    "TickRecord",
    "Trial",
    "TrialConfig",
    "TrialConfigError",
    "TrialError",
    "TrialResult",
    "run_trial",
]
