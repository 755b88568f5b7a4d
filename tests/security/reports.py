"""What the hostile-value tests ask of the reports a round issues after its run."""

from __future__ import annotations

import io

from pypdf import PdfReader

from analysis.models import Report
from analysis.reports.services import report_issue
from labs.models import Participant
from proficiency.models import Comparison


def assert_reports_name_and_finite(comparison: Comparison, code: str) -> None:
    """Issue the participant ``code``'s report and the summary: each names ``code`` and
    prints no ``nan`` or ``inf`` as a word."""
    comparison.refresh_from_db()
    participant = Participant.objects.get(comparison=comparison, code=code)
    for report in (
        report_issue(comparison=comparison, kind=Report.Kind.PARTICIPANT, participant=participant),
        report_issue(comparison=comparison, kind=Report.Kind.SUMMARY),
    ):
        with report.file.open("rb") as f:
            text = "\n".join(p.extract_text() for p in PdfReader(io.BytesIO(f.read())).pages)
        words = text.lower().split()
        assert code in text and "nan" not in words and "inf" not in words
