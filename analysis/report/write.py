"""The study report: HTML (self-contained, figures as inline SVG), Markdown, results.json.

``write_report(tables, out_dir)`` runs :func:`analysis.results.analyse`, draws the figures, and
writes ``report.html``, ``report.md``, ``results.json`` and ``figures/*.png|svg`` into
``out_dir``. Where the design (and for prediction, the predictors) are the paper's, tables put
the paper's published value beside ours; otherwise the report says why none are shown. The
header names the data source, the software version and the protocol's content hash; the
prediction section names the predictor parameters replayed (the protocol's, else the paper's).
The sections are those of :mod:`analysis.sections`, in its order.
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from analysis.errors import AnalysisError
from analysis.load import StudyTables
from analysis.outcomes import success_comparisons, success_summary
from analysis.prediction_eval import PREDICTORS, PredictorChoice, protocol_predictors
from analysis.protocol_info import DEFAULT_PROTOCOL, ProtocolInfo, load_protocol_info
from analysis.render import TITLE, render_html, render_markdown
from analysis.report.document import results_document
from analysis.report.draw import draw_figures
from analysis.report.software import software_info
from analysis.results import StudyResults, analyse
from analysis.sections import ReportContext, report_sections


@dataclass(frozen=True)
class ReportFiles:
    html: Path
    markdown: Path
    results_json: Path
    figures: tuple[Path, ...]
    results: StudyResults


def write_report(
    tables: StudyTables,
    out_dir: str | Path,
    *,
    protocol_path: str | Path | None = None,
    predictors: Mapping[str, Mapping[str, Any]] | None = None,
    successful_only: bool = False,
    protocol: ProtocolInfo | None = None,
) -> ReportFiles:
    """Analyse ``tables`` and write report.html, report.md, results.json and figures/.

    Fig. 7, the protocol hash, the factor levels and the replayed predictors come from the
    protocol kept with the data (the store's text or the export's protocol.toml); the file
    ``protocol_path`` is read when the source keeps none (default: protocols/dragan2013.toml,
    and then a differing default file is not mentioned).

    ``predictors``: the configs to replay; by default the paper's two (amnesic, memory-based
    with eq. 9's squared velocity), each replaced by the protocol's table of the same kind if
    it has one.

    ``protocol``: the protocol already read (its factors, within or between, and rated items
    decide the analysis); by default it is read as above."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if protocol is not None:
        proto, proto_notes = protocol, list(protocol.notes)
    else:
        proto, proto_notes = _protocol(tables, protocol_path)
    if predictors is not None:
        choices = [
            PredictorChoice(n, dict(c), "given by the caller") for n, c in predictors.items()
        ]
    else:
        predictors, choices = protocol_predictors(proto.prediction if proto else None, PREDICTORS)
    res = analyse(
        tables,
        predictors=predictors,
        successful_only=successful_only,
        levels=proto.factors if proto is not None else None,
        between=proto.between if proto is not None else (),
        items=proto.rating_items if proto is not None else (),
    )
    res.notes = proto_notes + res.notes
    figures = draw_figures(
        res, tables, proto, out / "figures", predictors, successful_only=successful_only
    )
    meta = _meta(tables, proto, res, choices)
    if (
        tables.protocol_hash
        and proto
        and proto.content_hash
        and tables.protocol_hash != proto.content_hash
    ):
        res.notes.insert(
            0,
            "the protocol file's hash differs from the one recorded with the "
            "data: pass the protocol the study ran with (--protocol)",
        )
    ctx = ReportContext(
        res,
        tables,
        figures,
        choices,
        modes=proto.factors.get("mode") if proto is not None else None,
        successful_only=successful_only,
    )
    return _write(out, ctx, meta)


def _protocol(
    tables: StudyTables, protocol_path: str | Path | None
) -> tuple[ProtocolInfo | None, list[str]]:
    """The protocol kept with the data, else the file (see :func:`write_report`), and notes;
    ``None`` and why when none can be read."""
    try:
        proto = load_protocol_info(
            protocol_path or DEFAULT_PROTOCOL,
            stored=tables.source,
            explicit=protocol_path is not None,
        )
    except AnalysisError as e:
        return None, [f"protocol not read (no Fig. 7, no hash): {e}"]
    return proto, list(proto.notes)


def _meta(
    tables: StudyTables,
    proto: ProtocolInfo | None,
    res: StudyResults,
    choices: Sequence[PredictorChoice],
) -> dict[str, Any]:
    """The report's header: title, source, time, software, protocol, participants, predictors."""
    return {
        "title": TITLE,
        "source": tables.source,
        "generated_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "software": software_info(),
        "protocol": {
            "path": proto.path if proto else None,
            "id": proto.study_id if proto else None,
            "content_hash": proto.content_hash if proto else None,
            "store_hash": tables.protocol_hash,
        },
        "participants": int(res.cells["participant"].nunique()) if not res.cells.empty else 0,
        "predictors": {c.name: {"config": c.config, "source": c.source} for c in choices},
    }


def _write(out: Path, ctx: ReportContext, meta: Mapping[str, Any]) -> ReportFiles:
    """report.html, report.md and results.json of ``ctx``'s sections into ``out``."""
    res, trials, modes = ctx.res, ctx.tables.trials, ctx.modes
    sections = report_sections(ctx)
    html_path, md_path, json_path = out / "report.html", out / "report.md", out / "results.json"
    html_path.write_text(render_html(sections, meta), encoding="utf-8")
    md_path.write_text(render_markdown(sections, meta), encoding="utf-8")
    success = (
        success_summary(trials, modes=modes),
        success_comparisons(trials, modes=modes) if res.inferential else pd.DataFrame(),
    )
    json_path.write_text(
        json.dumps(results_document(res, meta, success=success), indent=1, allow_nan=False),
        encoding="utf-8",
    )
    paths = tuple(p for f in ctx.figures.values() for p in (f.png, f.svg))
    return ReportFiles(
        html=html_path, markdown=md_path, results_json=json_path, figures=paths, results=res
    )
