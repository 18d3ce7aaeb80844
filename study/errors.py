"""The root of every error the study layer raises on purpose.

``StudyError`` is what a caller catches to mean "the study said no" (a malformed protocol, a
damaged store, an unknown participant, a refused message): each package's own root derives
from it, most also from the builtin a caller may already expect (``ProtocolError`` is a
``ValueError``, ``StoreError`` a ``RuntimeError``). ``python -m study`` catches it once and
prints its message on one line; anything else reaching the top is a bug.
"""

from __future__ import annotations


class StudyError(Exception):
    """An error the study layer raises on purpose; its message says what to do."""
