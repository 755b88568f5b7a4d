"""``/api/v1/`` routes (docs/interfaces.md §3: these names are a promise)."""

from django.urls import path

from labs.api import enrolment_views, raw_views, views

app_name = "api"

urlpatterns = [
    path("", views.ApiRoot.as_view(), name="root"),
    path("calls/", enrolment_views.CallList.as_view(), name="call-list"),
    path("comparisons/", views.ComparisonList.as_view(), name="comparison-list"),
    path("comparisons/<slug:code>/", views.ComparisonDetail.as_view(), name="comparison-detail"),
    path(
        "comparisons/<slug:code>/measurands/",
        views.MeasurandList.as_view(),
        name="measurand-list",
    ),
    path(
        "comparisons/<slug:code>/template.csv",
        views.ResultsTemplate.as_view(),
        name="results-template",
    ),
    path(
        "comparisons/<slug:code>/submissions/",
        views.SubmissionCollection.as_view(),
        name="submission-list",
    ),
    path(
        "comparisons/<slug:code>/submissions/upload/",
        views.SubmissionUpload.as_view(),
        name="submission-upload",
    ),
    path(
        "comparisons/<slug:code>/submissions/<int:version>/",
        views.SubmissionDetail.as_view(),
        name="submission-detail",
    ),
    path(
        "comparisons/<slug:code>/applications/",
        enrolment_views.ApplicationCollection.as_view(),
        name="application-list",
    ),
    path(
        "comparisons/<slug:code>/applications/<int:pk>/accept/",
        enrolment_views.ApplicationAccept.as_view(),
        name="application-accept",
    ),
    path(
        "comparisons/<slug:code>/applications/<int:pk>/decline/",
        enrolment_views.ApplicationDecline.as_view(),
        name="application-decline",
    ),
    path(
        "comparisons/<slug:code>/raw-data/",
        raw_views.RawDataCollection.as_view(),
        name="raw-data-list",
    ),
    path(
        "comparisons/<slug:code>/raw-data/<int:pk>/",
        raw_views.RawDataDetail.as_view(),
        name="raw-data-detail",
    ),
]
