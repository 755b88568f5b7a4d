"""A report as it would be issued now, for the coordinator's check before publication:
rendered from the current run on request, marked "preview", never stored or numbered as
an issued report (docs/lifecycles.md, reports)."""

from __future__ import annotations

from analysis.reports.assemble import report_data
from analysis.reports.render import render_report
from analysis.selectors import current_run
from common.errors import StateConflict
from labs.models import Participant
from proficiency.models import Comparison

#: The status printed on a preview (cover table and footer)
PREVIEW = "preview"


def report_preview(*, comparison: Comparison, participant: Participant | None = None) -> bytes:
    """The PDF of the summary (``participant`` None) or of one participant's report."""
    run = current_run(comparison)
    if run is None:
        raise StateConflict(f"{comparison.code} has no successful analysis run to preview.")
    return render_report(report_data(run=run, participant=participant, status=PREVIEW))
