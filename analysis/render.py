"""Rendering the report: tables and sections as Markdown and as self-contained HTML.

Numbers are formatted once (``fmt``, ``fmt_p``: APA-style p values); HTML escapes every cell
and embeds figures as inline SVG, so the file needs nothing beside it.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from analysis.figures import SavedFigure


@dataclass
class Table:
    title: str
    frame: pd.DataFrame
    note: str = ""


@dataclass
class Section:
    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)
    figures: list[SavedFigure] = field(default_factory=list)


def fmt(x: Any, digits: int = 2) -> str:
    """Numbers for tables: fixed decimals, '' for missing, text unchanged."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    if isinstance(x, bool | np.bool_):
        return str(bool(x))
    if isinstance(x, int | np.integer):
        return str(int(x))
    if isinstance(x, float | np.floating):
        if float(x).is_integer() and abs(x) < 1e6 and digits <= 0:
            return str(int(x))
        return f"{x:.{digits}f}"
    return str(x)


def fmt_p(p: Any) -> str:
    """APA-style p: '< .001' below one in a thousand, else three decimals without the zero."""
    if p is None or (isinstance(p, float) and math.isnan(p)):
        return ""
    if p < 0.001:
        return "< .001"
    return f"{p:.3f}".replace("0.", ".", 1) if p < 1 else "1.000"


def md_table(df: pd.DataFrame) -> str:
    def cell(v: Any) -> str:
        return str(v).replace("|", "\\|").replace("\n", " ")

    head = "| " + " | ".join(cell(c) for c in df.columns) + " |"
    sep = "|" + "|".join("---" for _ in df.columns) + "|"
    body = ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([head, sep, *body])


def html_table(df: pd.DataFrame) -> str:
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in row) + "</tr>"
        for row in df.itertuples(index=False)
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _header(meta: Mapping[str, Any]) -> list[tuple[str, str]]:
    sw, pr = meta["software"], meta["protocol"]
    items = [
        ("Data", meta["source"]),
        ("Generated", meta["generated_at"]),
        (
            "Software",
            f"{sw['package']} {sw['version']} (commit {sw['commit']}); Python "
            f"{sw['python']}, numpy {sw['numpy']}, pandas {sw['pandas']}, scipy "
            f"{sw['scipy']}, statsmodels {sw['statsmodels']}, matplotlib "
            f"{sw['matplotlib']}",
        ),
        (
            "Protocol",
            f"{pr.get('id') or '?'} from {pr.get('path') or 'no protocol file'}; "
            f"content hash {pr.get('content_hash') or 'unknown'}",
        ),
    ]
    if pr.get("store_hash"):
        match = "matches" if pr.get("store_hash") == pr.get("content_hash") else "DIFFERS"
        items.append(("Protocol hash recorded with the data", f"{pr['store_hash']} ({match})"))
    return items


TITLE = "Shared-control study report (Dragan & Srinivasa 2013 analyses)"
CSS = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;
color:#222}table{border-collapse:collapse;margin:.5em 0 1.5em;font-size:.9em}
td,th{border:1px solid #ccc;padding:.25em .6em;text-align:left}th{background:#f3f3f3}
figure{margin:1em 0}figure svg{max-width:100%;height:auto}figcaption{font-size:.9em;color:#555}
.meta td:first-child{font-weight:600}"""


def render_markdown(sections: list[Section], meta: Mapping[str, Any]) -> str:
    lines = [f"# {TITLE}", ""]
    lines += [f"- **{k}:** {v}" for k, v in _header(meta)] + [""]
    for sec in sections:
        lines += [f"## {sec.title}", ""]
        for p in sec.paragraphs:
            lines += [p, ""]
        for t in sec.tables:
            lines += [f"**{t.title}**", "", md_table(t.frame), ""]
            if t.note:
                lines += [f"_{t.note}_", ""]
        for f in sec.figures:
            lines += [
                f"![{f.title}](figures/{f.png.name})",
                "",
                f"_{f.title}_ ([SVG](figures/{f.svg.name}))",
                "",
            ]
    return "\n".join(lines)


def render_html(sections: list[Section], meta: Mapping[str, Any]) -> str:
    e = html.escape
    parts = [
        f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{e(TITLE)}"
        f"</title><style>{CSS}</style></head><body><h1>{e(TITLE)}</h1>",
        "<table class='meta'>"
        + "".join(f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in _header(meta))
        + "</table>",
    ]
    for sec in sections:
        parts.append(f"<h2>{e(sec.title)}</h2>")
        parts += [f"<p>{e(p)}</p>" for p in sec.paragraphs]
        for t in sec.tables:
            parts.append(f"<h3>{e(t.title)}</h3>{html_table(t.frame)}")
            if t.note:
                parts.append(f"<p><em>{e(t.note)}</em></p>")
        for f in sec.figures:
            parts.append(f"<figure>{f.inline_svg()}<figcaption>{e(f.title)}</figcaption></figure>")
    parts.append("</body></html>")
    return "\n".join(parts)
