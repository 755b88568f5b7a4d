"""Analysis and results web pages: run button, live progress, runs list, results
(assigned values, scores with downloads, charts, compatibility heat maps) and publication
(asked for here, run in the background, its progress polled like a run's).

The results pages serve two audiences with the same views and templates:

* ``coordinator`` (``/coordinator/<code>/results/...``): any successful run (``?run=``);
* ``participant`` (``/results/<code>/...``): only after publication, the current run,
  laboratories by code only, the reader's own code highlighted.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.core.paginator import Page, Paginator
from django.db.models import Count, IntegerField, OuterRef, QuerySet, Subquery
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse
from django.views.decorators.http import require_GET, require_POST

from analysis import chart_specs, charts
from analysis.archive import archive_shown
from analysis.chart_cache import cached_chart
from analysis.forms import CompatibilityForm, ScoreFilterForm
from analysis.history import lab_history
from analysis.history_chart import CAPTION as HISTORY_CAPTION
from analysis.history_views import trend_chart
from analysis.models import AnalysisRun, AssignedValue, Publication, RoundArchive, Score
from analysis.performance import lab_performance, performance
from analysis.publication import active_publication, publication_start
from analysis.selectors import (
    EXACT_MAX,
    approximate_subsets,
    current_run,
    lab_matrices,
    run_consistency,
    run_matrices,
    run_scores,
    score_columns_of,
    score_records,
)
from analysis.services import analysis_run_cancel, analysis_run_start
from analysis.viewer import COORDINATOR, Viewer
from common.errors import ApplicationError
from common.points import group_text
from common.quantities import shown_group
from common.sizes import database_id
from labs.access import coordinated, coordinated_comparisons, published_participation
from labs.importers import write_table
from proficiency.models import Comparison, ComparisonStatus, MeasurementPoint
from proficiency.selectors import POINT_ORDER

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest

R = AnalysisRun.Status
FLAG_CLASS = {"satisfactory": "text-bg-success", "warning": "text-bg-warning",
              "action": "text-bg-danger", "not scored": "text-bg-secondary"}  # fmt: skip
CONTENT_TYPES = {
    "csv": "text/csv; charset=utf-8",
    "xlsx": "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
}


def _viewer(request: AuthenticatedHttpRequest, code: str, audience: str) -> Viewer:
    if audience == COORDINATOR:
        comparison = coordinated(request, code)
        return Viewer(comparison, _chosen_run(comparison, request.GET.get("run", "")), audience)
    participant = published_participation(request, code)
    comparison = participant.comparison
    return Viewer(comparison, current_run(comparison), audience, own_code=participant.code)


def _chosen_run(comparison: Comparison, run_id: str) -> AnalysisRun | None:
    pk = database_id(run_id)
    if pk is None:  # no run asked for, or not a run's id: the current one
        return current_run(comparison)
    runs = comparison.analysis_runs.filter(status=R.SUCCEEDED)
    return get_object_or_404(runs, pk=pk)


def _render(request: HttpRequest, viewer: Viewer, page: str, context: dict) -> HttpResponse:
    base = {"viewer": viewer, "comparison": viewer.comparison, "run": viewer.run, "page": page,
            "current": viewer.current}  # fmt: skip
    if viewer.run is None:
        return render(request, "analysis/no_results.html", base)
    return render(request, f"analysis/{page}.html", base | context)


def _page(
    request: HttpRequest, items: QuerySet[Any] | Sequence[Any], per_page: int
) -> tuple[Page, str]:
    """The requested page of ``items`` and the request's query without ``page`` (the
    pagination links add their own)."""
    query = request.GET.copy()
    query.pop("page", None)
    return Paginator(items, per_page).get_page(request.GET.get("page")), query.urlencode()


# --- runs ---------------------------------------------------------------------------------


@login_required
@require_POST
def run_start(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    try:
        run = analysis_run_start(comparison=comparison, user=request.user)
    except ApplicationError as exc:
        messages.error(request, exc.message)
        return redirect("coordinator:comparison", code=code)
    return redirect("coordinator:run", code=code, pk=run.pk)


@login_required
@require_GET
def runs(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    context = {
        "comparison": comparison,
        "runs": _page(request, comparison.analysis_runs.select_related("created_by"), 25)[0],
        "current": current_run(comparison),
    }
    return render(request, "analysis/runs.html", context)


def _run(request: AuthenticatedHttpRequest, code: str, pk: int) -> AnalysisRun:
    comparison = coordinated(request, code)
    return get_object_or_404(comparison.analysis_runs.select_related("comparison"), pk=pk)


@login_required
@require_GET
def run_detail(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    run = _run(request, code, pk)
    context: dict[str, object] = {
        "comparison": run.comparison,
        "run": run,
        "current": current_run(run.comparison),
    }
    if run.status == R.SUCCEEDED:
        context["n_signalling"] = run_consistency(run, signals_only=True).count()
    return render(request, "analysis/run.html", context)


@login_required
@require_GET
def run_progress(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """The progress partial, polled by htmx: reads the run row, never the Celery backend."""
    run = _run(request, code, pk)
    context = {"comparison": run.comparison, "run": run, "current": current_run(run.comparison)}
    return render(request, "analysis/_progress.html", context)


@login_required
@require_POST
def run_cancel(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """Cancel a pending or running run; the coordinator can start a new one at once."""
    run = _run(request, code, pk)
    try:
        analysis_run_cancel(run=run, user=request.user)
    except ApplicationError as exc:
        messages.error(request, exc.message)
    else:
        messages.success(request, f"Analysis run {pk} is cancelled; it keeps no results.")
    return redirect("coordinator:run", code=code, pk=pk)


@login_required
@require_POST
def publish(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """Ask for publication (after the confirmation page): refused at once with its reason,
    else the job's progress page, where the publication runs in the background."""
    comparison = coordinated(request, code)
    try:
        publication = publication_start(comparison=comparison, user=request.user)
    except ApplicationError as exc:
        messages.error(request, exc.message)
        if (active := active_publication(comparison)) is not None:
            return redirect("coordinator:publication", code=code, pk=active.pk)
        return redirect("coordinator:comparison", code=code)
    return redirect("coordinator:publication", code=code, pk=publication.pk)


def _publication(request: AuthenticatedHttpRequest, code: str, pk: int) -> Publication:
    comparison = coordinated(request, code)
    found = comparison.publications.select_related("comparison", "run", "requested_by")
    return get_object_or_404(found, pk=pk)


@login_required
@require_GET
def publication(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    job = _publication(request, code, pk)
    context = {"comparison": job.comparison, "publication": job}
    return render(request, "analysis/publication.html", context)


@login_required
@require_GET
def publication_progress(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """The progress partial, polled by htmx: reads the job's row."""
    job = _publication(request, code, pk)
    context = {"comparison": job.comparison, "publication": job}
    return render(request, "analysis/_publication_progress.html", context)


# --- results pages (both audiences) -------------------------------------------------------


def _assigned(run: AnalysisRun) -> QuerySet[AssignedValue]:
    n = (
        Score.objects.filter(run=run, result__measurement_point=OuterRef("measurement_point"))
        .values("run").annotate(c=Count("pk")).values("c")
    )  # fmt: skip
    return (
        AssignedValue.objects.filter(run=run)
        .select_related("measurement_point__device")
        .annotate(n_results=Subquery(n, output_field=IntegerField()))
        .order_by(*POINT_ORDER)
    )


def _bench_rows(run: AnalysisRun) -> list[dict]:
    """Linear vs curvilinear per device and axis (the study's Table 2, here for all labs)."""
    rows = []
    for m in run_matrices(run, "bench", {}):
        if shown_group(m.group).get("quantity"):  # the study's table is of magnitudes
            continue
        at = {level: i for i, level in enumerate(m.levels)}
        if not {"linear", "curvilinear"} <= at.keys():
            continue
        i, j = at["linear"], at["curvilinear"]
        rows.append({"device": m.group.get("device"), "axis": m.group.get("axis"),
                     "linear": (m.values[i], m.expanded_uncertainties[i]),
                     "curvilinear": (m.values[j], m.expanded_uncertainties[j]),
                     "en": m.en[i][j]})  # fmt: skip
    return rows


@login_required
@require_GET
def results(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "results", {})
    c = viewer.comparison
    assigned, query = _page(request, _assigned(viewer.run), 100)
    context = {
        "assigned": assigned,
        "query": query,  # an earlier run's pages keep ?run=
        "bench_rows": _bench_rows(viewer.run),
        "n_approximate": approximate_subsets(viewer.run),
        "exact_max": EXACT_MAX,
        "may_publish": viewer.is_coordinator and c.status == ComparisonStatus.ANALYSED
        and viewer.run == viewer.current,
        # a participant's landing page starts with how it did
        "summary": lab_performance(viewer.run, viewer.own_code) if viewer.own_code else None,
        "scores_url": viewer.url("scores"),
        **archive_context(viewer, archive_shown(viewer.run, viewer.own_code)),
        "charts_url": viewer.url("charts"),
        "overview": _overview(viewer, viewer.own_code) if viewer.own_code else None,
    }  # fmt: skip
    return _render(request, viewer, "results", context)


def archive_context(viewer: Viewer, archive: RoundArchive | None) -> dict[str, object]:
    """What ``analysis/_archive.html`` shows: the archive of the run shown (if any) and the
    reader's links to ask for it, poll it and download it."""
    assert viewer.run is not None
    prefix = "" if viewer.is_coordinator else "lab_"
    download = reverse(f"coordinator:{prefix}archive_download",
                       args=[viewer.comparison.code, viewer.run.pk])  # fmt: skip
    urls = {"ask": viewer.url("archive"), "status": viewer.url("archive_status"),
            "download": download}  # fmt: skip
    return {"archive": archive, "archive_urls": urls}


@login_required
@require_GET
def performance_page(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    """Coordinator: every participant's flag counts in the run, 50 laboratories a page."""
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "performance", {})
    page, query = _page(request, _lab_codes(viewer), 50)
    context = {"page_obj": page, "rows": performance(viewer.run, page.object_list),
               "query": query}  # fmt: skip
    return _render(request, viewer, "performance", context)


@login_required
@require_GET
def participant_performance(
    request: AuthenticatedHttpRequest, code: str, lab: str, audience: str
) -> HttpResponse:
    """Coordinator: one participant's summary, as the participant sees it on its results,
    and its laboratory's history over the published rounds this coordinator coordinates
    (docs/domain.md §4.1)."""
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "participant_performance", {})
    participant = viewer.comparison.participants.select_related("laboratory").filter(code=lab)
    found = participant.first()
    if found is None:
        raise Http404(f"{code} has no participant {lab}.")
    history = lab_history(found.laboratory, within=coordinated_comparisons(request.user))
    context = {"lab": lab, "summary": lab_performance(viewer.run, lab),
               "scores_url": viewer.url("scores"), "history": history,
               "chart": trend_chart(history), "chart_caption": HISTORY_CAPTION,
               "within_note": "that you coordinate",
               "charts_url": viewer.url("charts"), "overview": _overview(viewer, lab)}  # fmt: skip
    return _render(request, viewer, "participant_performance", context)


def _overview(viewer: Viewer, lab: str) -> dict[str, Any]:
    """One participant's En and z over all its points (its results page, the coordinator's
    page of it), drawn once per run and participant."""
    return chart_specs.figure(viewer, chart_specs.overview_spec(viewer, lab))


def _lab_codes(viewer: Viewer) -> list[str]:
    return list(viewer.comparison.participants.order_by("code").values_list("code", flat=True))


@login_required
@require_GET
def scores(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "scores", {})
    form = ScoreFilterForm(request.GET, comparison=viewer.comparison, lab_codes=_lab_codes(viewer))
    page, query = _page(request, run_scores(viewer.run, form.filters(), form.ordering()), 50)
    own = viewer.own_code
    rows = [{"s": s, "flag_class": FLAG_CLASS.get(s.flag, ""),
             "z_flag_class": FLAG_CLASS.get(s.z_flag, ""),
             "own": s.result.submission.participant.code == own} for s in page]  # fmt: skip
    context = {"form": form, "page_obj": page, "rows": rows, "query": query}
    return _render(request, viewer, "scores", context)


@login_required
@require_GET
def scores_download(
    request: AuthenticatedHttpRequest, code: str, fmt: str, audience: str
) -> HttpResponse:
    """The (filtered) scores as CSV or XLSX; formula-like cells are escaped by write_table."""
    if fmt not in CONTENT_TYPES:
        raise Http404("Scores come as .csv or .xlsx.")
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        raise Http404(f"{code} has no analysed results yet.")
    form = ScoreFilterForm(request.GET, comparison=viewer.comparison, lab_codes=_lab_codes(viewer))
    records = score_records(viewer.run, form.filters())
    columns = score_columns_of(viewer.comparison)
    data = write_table(records, format=fmt, columns=columns)  # type: ignore[arg-type]
    response = HttpResponse(data, content_type=CONTENT_TYPES[fmt])
    name = f"{viewer.comparison.code}-scores-run{viewer.run.pk}.{fmt}"
    response["Content-Disposition"] = f'attachment; filename="{name}"'
    return response


def _run_points(run: AnalysisRun) -> list[MeasurementPoint]:
    return [a.measurement_point for a in _assigned(run)]


def _digest(en: Any) -> str:
    """A matrix's En values in the key: a lab matrix is computed on request from filters."""
    return hashlib.sha256(np.asarray(en, dtype=float).tobytes()).hexdigest()[:16]


def _matrix_view(title: str, m: Any, viewer: Viewer) -> dict:  # stored, or lab_matrices' (Any)
    levels = [str(v) if not isinstance(v, float) else f"{v:g} Hz" for v in m.levels]
    values = getattr(m, "values", None) or list(m.value)
    big_u = getattr(m, "expanded_uncertainties", None) or list(m.expanded_uncertainty)
    assert viewer.run is not None
    limit = viewer.comparison.en_limit
    parts = (title, tuple(levels), viewer.own_code, limit, _digest(m.en))
    svg = cached_chart(viewer.run, "heatmap", parts, lambda: charts.heatmap(
        levels, m.en, title=title, limit=limit, highlight=viewer.own_code))  # fmt: skip
    return {"title": title, "svg": svg, "incompatible": int(m.incompatible_pairs),
            "levels": list(zip(levels, values, big_u, strict=True))}  # fmt: skip


def _matrices(viewer: Viewer, form: CompatibilityForm) -> tuple[list, str]:
    factor = form.chosen_factor()
    assert viewer.run is not None
    if factor == "lab":
        try:
            found = lab_matrices(viewer.run, form.point_filters())
        except ApplicationError as exc:
            return [], exc.message
        return [(group_text(m.group, "="), m) for m in found], ""
    filters = {k: v for k, v in form.filters().items() if k != "lab"}
    return [(group_text(m.group, "=") or "all", m)
            for m in run_matrices(viewer.run, factor, filters)], ""  # fmt: skip


@login_required
@require_GET
def compatibility(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "compatibility", {})
    form = CompatibilityForm(request.GET, comparison=viewer.comparison,
                             points=_run_points(viewer.run))  # fmt: skip
    found, error = _matrices(viewer, form)
    page, query = _page(request, found, 6)
    context = {
        "form": form,
        "factor": form.chosen_factor(),
        "error": error,
        "page_obj": page,
        "matrices": [_matrix_view(title, m, viewer) for title, m in page],
        "query": query,
    }
    return _render(request, viewer, "compatibility", context)
