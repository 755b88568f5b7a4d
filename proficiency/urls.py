"""URL configuration."""

from django.contrib import admin
from django.urls import path

admin.site.site_header = "Proficiency testing — administration"
admin.site.site_title = "PT administration"

urlpatterns = [
    path("admin/", admin.site.urls),
]
