"""The course of the run in the certificate PDF: who started it and every action on it, from
the content's ``run_record`` (its audit trail). Text only comes from the content."""

from __future__ import annotations

from typing import Any

from station.certificates.pdf_layout import Flow


def record_section(f: Flow, c: dict[str, Any]) -> None:
    """Who started the run, then one line per action (UTC time, who, what)."""
    record = c.get("run_record")
    if not isinstance(record, dict):
        return
    f.subheading("Course of the run (audit trail: every action, who took it, UTC)")
    f.paragraph(f"Run started by: {record.get('started_by', 'not recorded')}.")
    for line in record.get("actions") or []:
        f.paragraph(str(line), size=7.0)
