"""Web pages of the laboratories, under ``/lab/`` (the REST API lives under ``/api/v1/``)."""

from django.urls import path

from labs import kit_views, views

app_name = "labs"

urlpatterns = [
    path("lab/", views.dashboard, name="dashboard"),
    path("lab/notices/read/", views.notices_read_all, name="notices_read_all"),
    path("lab/calls/", views.calls, name="calls"),
    path("lab/calls/<slug:code>/apply/", views.call_apply, name="call_apply"),
    path(
        "lab/applications/<int:pk>/withdraw/",
        views.application_withdraw,
        name="application_withdraw",
    ),
    path("lab/notices/<int:pk>/read/", views.notice_read, name="notice_read"),
    path("lab/comparisons/<slug:code>/", views.comparison_detail, name="comparison"),
    path("lab/comparisons/<slug:code>/results/", views.results_grid, name="grid"),
    path("lab/comparisons/<slug:code>/upload/", views.results_upload, name="upload"),
    path(
        "lab/comparisons/<slug:code>/template.<str:fmt>",
        views.results_template,
        name="template",
    ),
    path("lab/comparisons/<slug:code>/submissions/", views.submission_history, name="history"),
    path(
        "lab/comparisons/<slug:code>/submissions/<int:version>/",
        views.submission_detail,
        name="submission",
    ),
    path("lab/comparisons/<slug:code>/raw-data/", views.raw_data, name="raw_data"),
    path(
        "lab/comparisons/<slug:code>/raw-data/<int:pk>/",
        views.raw_record,
        name="raw_record",
    ),
    path("lab/comparisons/<slug:code>/kit/", kit_views.kit_page, name="kits"),
    path(
        "lab/comparisons/<slug:code>/kit/<int:pk>/received/",
        kit_views.kit_received,
        name="kit_received",
    ),
    path(
        "lab/comparisons/<slug:code>/kit/<int:pk>/dispatched/",
        kit_views.kit_dispatched,
        name="kit_dispatched",
    ),
    path("lab/api-keys/", views.api_keys_index, name="api_keys_index"),
    path("lab/<int:lab_pk>/api-keys/", views.api_keys, name="api_keys"),
    path(
        "lab/<int:lab_pk>/api-keys/<str:prefix>/revoke/",
        views.api_key_revoke,
        name="api_key_revoke",
    ),
]
