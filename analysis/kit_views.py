"""The page of a run's kits (docs/domain.md §13, §14): the drift judged per kit and point,
the reference each point was linked to with χ², and each participant's kit, date, drift
handling and degree of equivalence against that reference.

The coordinator reads every participant's row and the run's messages.  A participant
reads the round-level figures (the drift of each kit, the kit values, χ²) and its own
rows only: which kit another laboratory had and when is its circulation plan, shown to
no one else (§15), and the run's messages name laboratories and their kits.

The coordinator also reads, per linked point, the correlations between the participants'
degrees of equivalence (§14): a matrix of r for a point of at most
:data:`~analysis.kit_results.MATRIX_MAX` participants, else its largest pairs; the whole,
covariance and r per pair at full precision, is a CSV download.  A participant reads
none: they are other laboratories' numbers."""

from __future__ import annotations

import tempfile
from typing import TYPE_CHECKING, Any

from django.contrib.auth.decorators import login_required
from django.http import FileResponse, Http404, HttpResponse
from django.views.decorators.http import require_GET

from analysis.kit_results import (
    COVARIANCE_COLUMNS,
    MATRIX_MAX,
    DoeCovariance,
    covariance_rows,
    kit_covariances,
    kit_fits,
    kit_scores,
    kit_summary,
)
from analysis.models import AnalysisRun
from analysis.views import _page, _render, _viewer
from common import numbers
from labs.importers import write_table_to

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest


@login_required
@require_GET
def kits_page(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "kits", {})
    own = None if viewer.is_coordinator else viewer.own_code
    page, query = _page(request, kit_scores(viewer.run, own), 100)
    summary = kit_summary(viewer.run)
    if own is not None and summary is not None:
        summary.notes = []  # they name laboratories and their kits
    context = {"summary": summary, "fits": kit_fits(viewer.run), "page_obj": page, "query": query,
               "correlations": correlation_views(viewer.run) if own is None else [],
               "matrix_max": MATRIX_MAX}  # fmt: skip
    return _render(request, viewer, "kits", context)


def correlation_views(run: AnalysisRun) -> list[dict[str, Any]]:
    """Per linked point, its correlations as the page writes them (r to 2 decimals)."""
    return [_correlation_view(c) for c in kit_covariances(run)]


def _correlation_view(c: DoeCovariance) -> dict[str, Any]:
    view: dict[str, Any] = {"point": c.point, "reference": c.reference, "n": len(c.codes)}
    if len(c.codes) <= MATRIX_MAX:
        r = c.correlation
        view["codes"] = c.codes
        view["rows"] = [(a, [numbers.fixed(x, 2) if x == x else "—" for x in r[i].tolist()])
                        for i, a in enumerate(c.codes)]  # fmt: skip
    else:
        view["pairs"] = [(a, b, numbers.fixed(x, 2)) for a, b, x in c.largest()]
    return view


@login_required
@require_GET
def kit_covariance_download(request: AuthenticatedHttpRequest, code: str,
                            audience: str) -> FileResponse:  # fmt: skip
    """Every linked point's covariances and correlations in long form, full precision
    (``analysis.kit_results.covariance_rows``; docs/interfaces.md §6): the coordinator's."""
    viewer = _viewer(request, code, audience)
    if viewer.run is None or not viewer.is_coordinator:
        raise Http404(f"{code} has no linked results for you.")
    out = tempfile.TemporaryFile()  # noqa: SIM115 - closed by the response
    write_table_to(out, covariance_rows(viewer.run), format="csv", columns=COVARIANCE_COLUMNS)
    out.seek(0)
    name = f"{viewer.comparison.code}-doe-covariance-run{viewer.run.pk}.csv"
    return FileResponse(
        out, as_attachment=True, filename=name, content_type="text/csv; charset=utf-8"
    )
