"""Section "Contacts: the arm touching objects" (:mod:`analysis.contact_summary`)."""

from __future__ import annotations

from analysis.contact_summary import contact_section
from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    return contact_section(ctx.tables)
