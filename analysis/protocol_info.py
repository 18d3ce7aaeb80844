"""What the report needs from a protocol file: its id and hash, the arbitration of each mode.

Read through ``study.protocol.load_protocol`` (validated, canonical content hash); if that
package is unavailable, the TOML is read directly and hashed byte for byte (said in the notes).
"""

from __future__ import annotations

import hashlib
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis.errors import SourceError

DEFAULT_PROTOCOL = Path(__file__).resolve().parents[1] / "protocols" / "dragan2013.toml"


@dataclass(frozen=True)
class ProtocolInfo:
    path: str
    study_id: str | None
    content_hash: str | None
    arbitrations: dict[str, Mapping[str, Any]]  # mode name -> [modes.<name>].arbitration
    amnesic_temperature: float = 0.05
    notes: tuple[str, ...] = field(default_factory=tuple)
    factors: dict[str, tuple[str, ...]] = field(default_factory=dict)  # [factors], in order


def _temperature(prediction: Mapping[str, Any] | None) -> float:
    for table in (prediction or {}).values():
        if isinstance(table, Mapping) and table.get("kind") == "amnesic":
            return float(table.get("temperature", 0.05))
    return 0.05


def load_protocol_info(path: str | Path = DEFAULT_PROTOCOL) -> ProtocolInfo:
    """Mode arbitration tables, id and content hash of the protocol at ``path``."""
    p = Path(path)
    if not p.exists():
        raise SourceError(f"no protocol file at {p}; pass --protocol PATH")
    try:
        from study.protocol import load_protocol
    except ImportError:
        load_protocol = None  # type: ignore[assignment]
    if load_protocol is not None:
        try:
            proto = load_protocol(p)
        except Exception as e:  # the protocol's typed errors name file, key and problem
            raise SourceError(f"cannot load the protocol {p}: {e}") from e
        return ProtocolInfo(
            path=str(p), study_id=proto.id, content_hash=proto.content_hash,
            arbitrations={m.name: dict(m.arbitration) for m in proto.modes
                          if m.arbitration is not None},
            amnesic_temperature=_temperature(proto.prediction),
            factors={k: tuple(map(str, v)) for k, v in dict(proto.factors).items()},
        )
    raw = p.read_bytes()
    try:
        doc = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SourceError(f"{p} is not valid TOML: {e}") from e
    modes = doc.get("modes", {})
    return ProtocolInfo(
        path=str(p), study_id=doc.get("study", {}).get("id"),
        content_hash=hashlib.sha256(raw).hexdigest(),
        arbitrations={k: v["arbitration"] for k, v in modes.items()
                      if isinstance(v, dict) and isinstance(v.get("arbitration"), dict)},
        amnesic_temperature=_temperature(doc.get("prediction")),
        factors={k: tuple(map(str, v)) for k, v in doc.get("factors", {}).items()
                 if isinstance(v, list)},
        notes=("study.protocol is unavailable: the protocol was read as plain TOML and its hash "
               "is the sha256 of the file's bytes",),
    )
