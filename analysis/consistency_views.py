"""The consistency page of a run's results (both audiences, like ``analysis.views``): per
measurement point the Grubbs and Cochran verdicts and each laboratory's Mandel h and k,
stragglers and outliers marked; laboratories by code only.  A CSV download gives the same
in long form at full precision (the ``pt_compare`` CSV section)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpResponse
from django.views.decorators.http import require_GET

from analysis import consistency as tests
from analysis.models import AssignedValue
from analysis.selectors import run_consistency
from analysis.views import Viewer, _page, _render, _viewer
from common.points import POINT_FIELDS
from labs.importers import write_table

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest

BADGE = {"correct": "text-bg-success", "straggler": "text-bg-warning",
         "outlier": "text-bg-danger", tests.NA: "text-bg-light border"}  # fmt: skip
TEST_ORDER = ("grubbs_single", "grubbs_double", "cochran")


@login_required
@require_GET
def consistency(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "consistency", {})
    signals = request.GET.get("signals") == "1"
    page, query = _page(request, run_consistency(viewer.run, signals_only=signals), 25)
    context = {
        "page_obj": page,
        "points": [point_view(a, viewer) for a in page],
        "signals": signals,
        "query": query,
        "n_signalling": run_consistency(viewer.run, signals_only=True).count(),
    }
    return _render(request, viewer, "consistency", context)


def point_view(a: AssignedValue, viewer: Viewer) -> dict[str, Any]:
    """One point's tests as the page shows them: statistics to 3 significant digits."""
    rec = a.consistency
    if not rec:  # a run stored before the consistency tests existed
        return {"point": a.measurement_point, "missing": True}
    return {
        "point": a.measurement_point,
        "rec": rec,
        "tests": [_test_view(name, rec[name]) for name in TEST_ORDER],
        "h": tests.flagged_labs(rec, "h"),
        "k": tests.flagged_labs(rec, "k"),
        "mandel": [_test_view(name, rec[name]) for name in ("mandel_h", "mandel_k")],
        "labs": [_lab_view(lab, viewer) for lab in rec["labs"]],
    }


def _test_view(name: str, t: dict[str, Any]) -> dict[str, Any]:
    crit = ""
    if t["applicable"]:
        crit = f"{tests.statistic_text(t['critical_5'])} / {tests.statistic_text(t['critical_1'])}"
    text = tests.detail_text(t) if name in TEST_ORDER else t.get("reason", "")
    return {"name": tests.TEST_NAMES[name], "verdict": t["verdict"], "badge": BADGE[t["verdict"]],
            "text": text, "critical": crit}  # fmt: skip


def _lab_view(lab: dict[str, Any], viewer: Viewer) -> dict[str, Any]:
    return {
        "code": lab["lab"],
        "own": lab["lab"] == viewer.own_code,
        "h": tests.statistic_text(lab["h"]) if lab["h"] is not None else "n/a",
        "h_badge": BADGE[lab["h_flag"]],
        "h_flag": lab["h_flag"],
        "k": tests.statistic_text(lab["k"]) if lab["k"] is not None else "n/a",
        "k_badge": BADGE[lab["k_flag"]],
        "k_flag": lab["k_flag"],
    }


@login_required
@require_GET
def consistency_download(
    request: AuthenticatedHttpRequest, code: str, audience: str
) -> HttpResponse:
    """Every point's tests in long form (``analysis.consistency.csv_rows``), full precision."""
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        raise Http404(f"{code} has no analysed results yet.")
    records = []
    for a in run_consistency(viewer.run, signals_only=False).iterator(chunk_size=500):
        p = a.measurement_point
        keys = dict(zip(POINT_FIELDS, p.key.measurand, strict=True))
        if a.consistency:
            records.append(keys | a.consistency)
    data = write_table(tests.csv_rows(records), columns=tests.CSV_COLUMNS)
    response = HttpResponse(data, content_type="text/csv; charset=utf-8")
    name = f"{viewer.comparison.code}-consistency-run{viewer.run.pk}.csv"
    response["Content-Disposition"] = f'attachment; filename="{name}"'
    return response
