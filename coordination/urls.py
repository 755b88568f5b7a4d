"""Coordinator web pages under ``/coordinator/`` and the participants' published results
under ``/results/`` (both in the ``coordinator`` namespace; analysis pages from
``analysis.urls``)."""

from django.urls import include, path

from coordination import kit_views, views

app_name = "coordinator"

C = "coordinator/<slug:code>/"

urlpatterns = [
    path("coordinator/", views.dashboard, name="dashboard"),
    path("coordinator/new/", views.comparison_create, name="create"),
    path(C, views.comparison_detail, name="comparison"),
    path(C + "edit/", views.comparison_edit, name="edit"),
    path(C + "status/", views.comparison_status, name="status"),
    path(C + "confirm/<slug:action>/", views.confirm, name="confirm"),
    path(C + "report-notes/", views.report_notes, name="report_notes"),
    path(C + "devices/new/", views.device_add, name="device_add"),
    path(C + "points/generate/", views.points_generate, name="points_generate"),
    path(C + "points/<int:pk>/", views.point_edit, name="point_edit"),
    path(C + "participants/invite/", views.participants_invite, name="invite"),
    path(C + "participants/<str:participant>/scope/", views.participant_scope, name="scope"),
    path(
        C + "participants/<str:participant>/reference/",
        views.participant_reference,
        name="reference",
    ),
    path(C + "applications/", views.applications, name="applications"),
    path(C + "applications/<int:pk>/accept/", views.application_accept, name="application_accept"),
    path(
        C + "applications/<int:pk>/decline/",
        views.application_decline,
        name="application_decline",
    ),
    path(C + "review/", views.review, name="review"),
    path(C + "review/accept-complete/", views.accept_complete, name="accept_complete"),
    path(
        C + "review/<str:participant>/v<int:version>/",
        views.submission_review,
        name="submission",
    ),
    path(C + "review/results/<int:pk>/check/", views.result_check, name="check"),
    path(C + "raw-data/", views.raw_review, name="raw_review"),
    path(C + "kits/", kit_views.kits_page, name="kits"),
    path(C + "kits/new/", kit_views.kit_new, name="kit_new"),
    path(C + "kits/<int:pk>/plan/", kit_views.kit_plan, name="kit_plan"),
    path(C + "kits/<int:pk>/dispatch/", kit_views.kit_dispatch, name="kit_dispatch"),
    path(C + "kits/<int:pk>/returned/", kit_views.kit_returned, name="kit_returned"),
    path(C + "kits/<int:pk>/measurements/", kit_views.kit_measurements, name="kit_measurements"),
    path("", include("analysis.urls")),
]
