"""Typed errors raised while loading a protocol file or checking an answer against it.

Every :class:`ProtocolError` names the file, the key path inside it (``tasks.easy-right.scene``)
and what is wrong, so an experimenter can fix the file without reading code.
"""

from __future__ import annotations

from pathlib import Path

from study.errors import StudyError


class ProtocolError(StudyError, ValueError):
    """A protocol file is not a valid study definition.

    Attributes:
        file: the protocol file (or ``"<string>"`` for text parsed without a file).
        key: dotted key path of the offending entry (``""`` for the whole file).
        problem: what is wrong and, where it helps, what to do.
    """

    def __init__(self, problem: str, *, file: Path | str, key: str) -> None:
        self.file = str(file)
        self.key = key
        self.problem = problem
        where = f"{self.file}: {key}" if key else self.file
        super().__init__(f"{where}: {problem}")


class ProtocolSyntaxError(ProtocolError):
    """The file is not valid TOML (including a key defined twice)."""


class MissingKeyError(ProtocolError):
    """A required key is absent."""


class UnknownKeyError(ProtocolError):
    """A key the format does not define (usually a typo)."""


class ProtocolTypeError(ProtocolError):
    """A value has the wrong type (a string where a number belongs, ...)."""


class ProtocolValueError(ProtocolError):
    """A value has the right type but is out of range or not one of the allowed choices."""


class ConditionConflictError(ProtocolError):
    """Two levels (or a level and a task) of one condition set the same value differently."""


class UndefinedReferenceError(ProtocolError):
    """A name refers to something the file does not define (a scene, a level, an item ...)."""


class ScaleMismatchError(ProtocolError):
    """A rating scale's anchors do not match the questionnaire's number of points."""


class BlindingError(ProtocolError):
    """Participant-facing text names a condition (e.g. a mode or correctness level)."""


class AnswerError(StudyError, ValueError):
    """An answer does not fit its item's scale (e.g. 8 on a 7-point item) or names no item."""


class ConditionError(StudyError, KeyError):
    """A task, mode or instruction phase that the loaded protocol does not define."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""
