"""Analysis and results pages; included by ``coordination.urls`` (namespace
``coordinator``).  The results views serve the coordinator and, after publication, the
participants (``lab_*`` names under ``/results/``)."""

from django.urls import path

from analysis import archive_views, chart_views, consistency_views, history_views, kit_views, views
from analysis.viewer import COORDINATOR, PARTICIPANT

C = "coordinator/<slug:code>/"
P = "results/<slug:code>/"
COORD = {"audience": COORDINATOR}
LAB = {"audience": PARTICIPANT}

urlpatterns = [
    # a laboratory's history across the published rounds (docs/domain.md §4.1)
    path("lab/history/", history_views.lab_history_page, name="lab_history"),
    path(C + "analysis/run/", views.run_start, name="run_start"),
    path(C + "analysis/runs/", views.runs, name="runs"),
    path(C + "analysis/runs/<int:pk>/", views.run_detail, name="run"),
    path(C + "analysis/runs/<int:pk>/progress/", views.run_progress, name="run_progress"),
    path(C + "analysis/runs/<int:pk>/cancel/", views.run_cancel, name="run_cancel"),
    path(C + "publish/", views.publish, name="publish"),
    path(C + "publication/<int:pk>/", views.publication, name="publication"),
    path(C + "performance/", views.performance_page, COORD, name="performance"),
    # the covariance of a kits round's linked degrees of equivalence (docs/domain.md §14)
    path(
        C + "results/kits/covariance.csv",
        kit_views.kit_covariance_download,
        COORD,
        name="results_kits_covariance",
    ),
    path(
        C + "performance/<slug:lab>/",
        views.participant_performance,
        COORD,
        name="participant_performance",
    ),
    path(
        C + "publication/<int:pk>/progress/",
        views.publication_progress,
        name="publication_progress",
    ),
]

for prefix, base, audience in (("", C, COORD), ("lab_", P, LAB)):
    urlpatterns += [
        path(base + "results/" if base == C else base, views.results, audience,
             name=prefix + "results"),
        path(base + "scores/", views.scores, audience, name=prefix + "scores"),
        # a kits round's drift and link (docs/domain.md §13, §14)
        path(base + ("results/kits/" if base == C else "kits/"), kit_views.kits_page, audience,
             name=prefix + "results_kits"),
        path(base + "scores.<str:fmt>", views.scores_download, audience,
             name=prefix + "scores_download"),
        path(base + "charts/", chart_views.charts_page, audience, name=prefix + "charts"),
        path(base + "charts/<slug:chart>.<str:ext>", chart_views.chart_download, audience,
             name=prefix + "chart_download"),
        path(base + "compatibility/", views.compatibility, audience,
             name=prefix + "compatibility"),
        path(base + "consistency/", consistency_views.consistency, audience,
             name=prefix + "consistency"),
        path(base + "consistency.csv", consistency_views.consistency_download, audience,
             name=prefix + "consistency_download"),
        path(base + "archive/", archive_views.archive_ask, audience, name=prefix + "archive"),
        path(base + "archive/status/", archive_views.archive_status, audience,
             name=prefix + "archive_status"),
        path(base + "archive/run<int:run>.zip", archive_views.archive_download, audience,
             name=prefix + "archive_download"),
    ]  # fmt: skip
