"""URL configuration."""

from django.contrib import admin
from django.urls import include, path

from proficiency import views

admin.site.site_header = "Proficiency testing — administration"
admin.site.site_title = "PT administration"

urlpatterns = [
    path("", views.home, name="home"),
    path("accounts/", include("django.contrib.auth.urls")),
    path("admin/", admin.site.urls),
]
