"""The run's reports: report.xlsx, summary.html, the manifest and what changed since the last run."""
