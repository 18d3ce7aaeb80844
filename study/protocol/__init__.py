"""Protocols: a study defined in TOML, validated on load.

from study.protocol import load_protocol
protocol = load_protocol("protocols/dragan2013.toml")
protocol.tasks, protocol.modes
protocol.trial_config("hard-right", "aggressive")   # -> app.trial.TrialConfig
protocol.describe_trial("hard-right")               # participant-facing, no condition word
protocol_from_store(store)                          # the exact protocol a store ran with
"""

from study.protocol.errors import (
    AnswerError,
    BlindingError,
    ConditionConflictError,
    ConditionError,
    MissingKeyError,
    ProtocolError,
    ProtocolSyntaxError,
    ProtocolTypeError,
    ProtocolValueError,
    ScaleMismatchError,
    UndefinedReferenceError,
    UnknownKeyError,
)
from study.protocol.loader import (
    content_hash,
    load_protocol,
    parse_protocol,
    trial_config_from_protocol,
)
from study.protocol.model import Control, Mode, StudyInfo, Task, Texts, Training
from study.protocol.protocol import TRAINING_MODE, Protocol
from study.protocol.questionnaire import (
    PHASES,
    Answer,
    AttentionItem,
    ChoiceItem,
    Item,
    LikertItem,
    NumberItem,
    Questionnaire,
    RetentionItem,
    Scale,
    TextItem,
)
from study.protocol.stored import StoredProtocolError, protocol_from_store

__all__ = [
    "PHASES",
    "TRAINING_MODE",
    "Answer",
    "AnswerError",
    "AttentionItem",
    "BlindingError",
    "ChoiceItem",
    "ConditionConflictError",
    "ConditionError",
    "Control",
    "Item",
    "LikertItem",
    "MissingKeyError",
    "Mode",
    "NumberItem",
    "Protocol",
    "ProtocolError",
    "ProtocolSyntaxError",
    "ProtocolTypeError",
    "ProtocolValueError",
    "Questionnaire",
    "RetentionItem",
    "Scale",
    "ScaleMismatchError",
    "StoredProtocolError",
    "StudyInfo",
    "Task",
    "TextItem",
    "Texts",
    "Training",
    "UndefinedReferenceError",
    "UnknownKeyError",
    "content_hash",
    "load_protocol",
    "parse_protocol",
    "protocol_from_store",
    "trial_config_from_protocol",
]
