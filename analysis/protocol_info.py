"""What the report needs from a protocol: its id and hash, the arbitration of each mode, the
factor levels (and which factors vary between subjects), the Likert items rated after each run
and the prediction tables.

The protocol the data were collected with comes first: the text a study store keeps
(``study.protocol.protocol_from_store``) or an export folder's ``protocol.toml``; then the file
passed with --protocol (by default protocols/dragan2013.toml), which may have been edited since;
only a file the user named is reported as differing from the stored protocol.
Read through ``study.protocol`` (validated, canonical content hash).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from analysis.errors import SourceError
from app.errors import AppError
from study.errors import StudyError
from study.store import Store

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_PROTOCOL = ROOT / "protocols" / "dragan2013.toml"


@dataclass(frozen=True)
class ProtocolInfo:
    path: str
    study_id: str | None
    content_hash: str | None
    arbitrations: dict[str, Mapping[str, Any]]  # mode name -> [modes.<name>].arbitration
    amnesic_temperature: float = 0.05
    notes: tuple[str, ...] = field(default_factory=tuple)
    factors: dict[str, tuple[str, ...]] = field(default_factory=dict)  # [factors], in order
    prediction: dict[str, dict[str, Any]] = field(default_factory=dict)  # [prediction.<name>]
    rate_hz: float = 100.0  # [control] rate_hz (builds arbitration kinds with time constants)
    between: tuple[str, ...] = ()  # the factors varied between subjects (the rest: within)
    rating_items: tuple[str, ...] = ()  # the Likert items asked after each run, in order

    @property
    def within(self) -> tuple[str, ...]:
        """The factors varied within subjects, in the protocol's order."""
        return tuple(f for f in self.factors if f not in self.between)


def _temperature(prediction: Mapping[str, Any] | None) -> float:
    for table in (prediction or {}).values():
        if isinstance(table, Mapping) and table.get("kind") == "amnesic":
            return float(table.get("temperature", 0.05))
    return 0.05


def _prediction_tables(prediction: Mapping[str, Any] | None) -> dict[str, dict[str, Any]]:
    """The protocol's [prediction.<name>] tables as plain dicts, in the protocol's order."""
    return {str(k): dict(v) for k, v in (prediction or {}).items() if isinstance(v, Mapping)}


def load_protocol_info(
    path: str | Path = DEFAULT_PROTOCOL,
    *,
    stored: str | Path | None = None,
    explicit: bool = True,
) -> ProtocolInfo:
    """Mode arbitration tables, id and content hash of the protocol the data were collected with:
    the one kept in ``stored`` (a study store, or an export folder with ``protocol.toml``) if it
    keeps one, else the protocol file at ``path``.

    ``explicit``: the user named ``path`` (--protocol); only then does a note say that it differs
    from the stored protocol and was not used (a default path the user never gave is not news).
    """
    if stored is not None:
        info, why = _stored_info(Path(stored))
        if info is not None:
            ignored = _ignored_file_note(info, path) if explicit else ()
            return replace(info, notes=info.notes + ignored)
        if why:
            file_info = _file_info(path)
            return replace(file_info, notes=(why, *file_info.notes))
    return _file_info(path)


def _stored_info(source: Path) -> tuple[ProtocolInfo | None, str | None]:
    """The protocol kept with the data at ``source``, or ``None`` and why (``None`` if there is
    nothing to say: the source cannot keep a protocol)."""
    if source.is_dir():
        kept = source / "protocol.toml"
        if not kept.is_file():
            return None, None
        try:
            return _file_info(kept), None
        except SourceError as e:
            return None, f"the protocol exported with the data was not used: {e}"
    if not source.is_file():
        return None, None
    # study.protocol loads app.robot (pinocchio, scipy.linalg): +0.8 s (-X importtime), paid
    # only when a protocol is read, not by every `import analysis.report`
    from study.protocol import protocol_from_store

    try:
        with Store.open_readonly(source) as store:
            proto = protocol_from_store(store)
    except (StudyError, AppError) as e:  # no stored text (old store), altered, no longer valid
        return None, f"the protocol stored with the data was not used: {e}"
    return _info(proto, path=f"{source} (stored protocol)"), None


def _ignored_file_note(info: ProtocolInfo, path: str | Path | None) -> tuple[str, ...]:
    """A note if the protocol file at ``path`` differs from the stored protocol ``info``."""
    if path is None or not Path(path).is_file():
        return ()
    try:
        other = _file_info(path).content_hash
    except SourceError:
        other = None
    if other == info.content_hash:
        return ()
    return (
        f"read the protocol stored with the data ({info.content_hash}); the protocol file "
        f"{path} differs ({other or 'unreadable'}) and was not used",
    )


def _info(proto: Any, *, path: str) -> ProtocolInfo:
    return ProtocolInfo(
        path=path,
        study_id=proto.id,
        content_hash=proto.content_hash,
        arbitrations={
            m.name: dict(m.arbitration) for m in proto.modes if m.arbitration is not None
        },
        amnesic_temperature=_temperature(proto.prediction),
        factors={k: tuple(map(str, v)) for k, v in dict(proto.factors).items()},
        prediction=_prediction_tables(proto.prediction),
        rate_hz=float(proto.control.rate_hz),
        # the factors-by-name protocol declares them; older ones have within factors only
        between=tuple(map(str, getattr(proto, "between_factors", ()))),
        rating_items=_rating_items(proto),
    )


def _rating_items(proto: Any) -> tuple[str, ...]:
    """The ids of the Likert items the protocol asks after each run (none if it asks none)."""
    questionnaire = getattr(proto, "questionnaire", None)
    return tuple(str(i.id) for i in getattr(questionnaire, "after_run", ()))


def _file_info(path: str | Path) -> ProtocolInfo:
    """The protocol file at ``path``."""
    p = Path(path)
    if not p.exists():
        raise SourceError(f"no protocol file at {p}; pass --protocol PATH")
    from study.protocol import load_protocol  # +0.8 s: see _stored_info

    try:
        proto = load_protocol(p)
    except (StudyError, AppError) as e:  # typed errors name file, key and problem
        raise SourceError(f"cannot load the protocol {p}: {e}") from e
    return _info(proto, path=str(p))
