"""URL configuration."""

from django.contrib import admin
from django.urls import include, path
from drf_spectacular.views import SpectacularAPIView, SpectacularSwaggerSplitView

from labs import views as lab_views
from proficiency.health import healthz

admin.site.site_header = "Proficiency testing — administration"
admin.site.site_title = "PT administration"

urlpatterns = [
    # Load balancer / systemd / container health check: database and broker, no auth, no data.
    path("healthz", healthz, name="healthz"),
    # The API first: its routes are the most requested (lab software polling), and every
    # pattern tried before them costs each request time (bench/README.md, "Load test").
    path("api/v1/", include("labs.api.urls")),
    path("api/v1/", include("analysis.api.urls")),
    path("api/v1/", include("proficiency.api")),
    path("api/v1/", include("analysis.reports.api")),
    # "/" is a lab member's dashboard, the public landing page for everyone else.
    path("", lab_views.home, name="home"),
    path("", include("labs.urls")),
    path("", include("proficiency.coordinator_urls")),
    path("", include("analysis.reports.views")),
    path("accounts/", include("django.contrib.auth.urls")),
    path("admin/", admin.site.urls),
    path("api/schema/", SpectacularAPIView.as_view(), name="schema"),
    # The split view serves Swagger UI's start-up script as a file (CSP: no inline script).
    path("api/docs/", SpectacularSwaggerSplitView.as_view(url_name="schema"), name="api-docs"),
]
