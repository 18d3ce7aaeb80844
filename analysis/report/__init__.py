"""The study report: ``write_report(tables, out_dir)`` writes report.html, report.md,
results.json and figures/ (:mod:`analysis.report.write`); the sections are those of
:mod:`analysis.sections`."""

from analysis.report.document import results_document
from analysis.report.software import software_info
from analysis.report.write import ReportFiles, write_report

__all__ = ["ReportFiles", "results_document", "software_info", "write_report"]
