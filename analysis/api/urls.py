"""Coordinator routes under ``/api/v1/`` (docs/interfaces.md §3 names)."""

from django.urls import path

from analysis.api import views

urlpatterns = [
    path(
        "comparisons/<slug:code>/analysis-runs/",
        views.AnalysisRunCollection.as_view(),
        name="analysis-run-list",
    ),
    path("analysis-runs/<int:pk>/", views.AnalysisRunDetail.as_view(), name="analysis-run-detail"),
    path(
        "analysis-runs/<int:pk>/cancel/",
        views.AnalysisRunCancel.as_view(),
        name="analysis-run-cancel",
    ),
    path("comparisons/<slug:code>/scores/", views.ScoreList.as_view(), name="score-list"),
    path(
        "comparisons/<slug:code>/doe-covariance/",
        views.DoeCovarianceList.as_view(),
        name="doe-covariance",
    ),
    path(
        "comparisons/<slug:code>/compatibility/",
        views.CompatibilityView.as_view(),
        name="compatibility",
    ),
    path("comparisons/<slug:code>/publish/", views.Publish.as_view(), name="publish"),
    path("publications/<int:pk>/", views.PublicationDetail.as_view(), name="publication-detail"),
    path(
        "comparisons/<slug:code>/transition/",
        views.ComparisonTransition.as_view(),
        name="comparison-transition",
    ),
    path(
        "comparisons/<slug:code>/submissions/<str:participant>/<int:version>/decision/",
        views.SubmissionDecision.as_view(),
        name="submission-decision",
    ),
    path(
        "comparisons/<slug:code>/check-requests/",
        views.RequestCheck.as_view(),
        name="check-request",
    ),
]
