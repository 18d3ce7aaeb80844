"""Trials: one input source -> blending -> robot loop, its configuration, records and outcome."""

from app.trial.config import TrialConfig
from app.trial.errors import TrialConfigError, TrialError

__all__ = ["TrialConfig", "TrialConfigError", "TrialError"]
