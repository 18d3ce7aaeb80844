"""The study report: ``write_report(tables, out_dir)`` writes report.html, report.md,
results.json and figures/ (:mod:`analysis.report.write`)."""

from analysis.report.write import ReportFiles, results_document, software_info, write_report

__all__ = ["ReportFiles", "results_document", "software_info", "write_report"]
