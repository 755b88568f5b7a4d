"""URL configuration."""

from django.contrib import admin
from django.contrib.auth import urls as auth_urls
from django.urls import include, path
from drf_spectacular.views import SpectacularAPIView, SpectacularSwaggerSplitView

from common.accounts import PasswordResetView
from common.health import healthz
from common.views import api_docs_guard
from labs import views as lab_views

admin.site.site_header = "Proficiency testing — administration"
admin.site.site_title = "PT administration"

# django.contrib.auth's pages, with the password reset throttled (common.accounts)
AUTH_URLS = [
    path("password_reset/", PasswordResetView.as_view(), name="password_reset"),
    *(p for p in auth_urls.urlpatterns if p.name != "password_reset"),  # type: ignore[union-attr]  # auth.urls: URLPatterns only
]

urlpatterns = [
    # Load balancer / systemd / container health check: database and broker, no auth, no data.
    path("healthz", healthz, name="healthz"),
    # The API first: its routes are the most requested (lab software polling), and every
    # pattern tried before them costs each request time (bench/README.md, "Load test").
    path("api/v1/", include("labs.api.urls")),
    path("api/v1/", include("analysis.api.urls")),
    path("api/v1/", include("coordination.api")),
    path("api/v1/", include("analysis.reports.api")),
    # "/" is a lab member's dashboard, the public landing page for everyone else.
    path("", lab_views.home, name="home"),
    path("", include("labs.urls")),
    path("", include("coordination.urls")),
    path("", include("analysis.reports.views")),
    path("accounts/", include(AUTH_URLS)),
    path("admin/", admin.site.urls),
    # for signed-in people unless API_DOCS_PUBLIC (README, "Configuration")
    path("api/schema/", api_docs_guard(SpectacularAPIView.as_view()), name="schema"),
    # The split view serves Swagger UI's start-up script as a file (CSP: no inline script).
    path(
        "api/docs/",
        api_docs_guard(SpectacularSwaggerSplitView.as_view(url_name="schema")),
        name="api-docs",
    ),
]

# a form field with a control character found by the CSRF check: 400 naming the field
handler400 = "common.middleware.bad_request"
