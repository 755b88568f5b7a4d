"""The Django admin is for superusers only.

Coordinators run their rounds through the coordinator pages and API, which scope every
query to the comparisons they coordinate. The admin cannot be scoped that way (it lists
every laboratory behind its code, every round's results, every API key), so it is closed
to everyone but superusers, whatever their staff flag or model permissions say.
"""

from django.contrib import admin
from django.contrib.admin.apps import AdminConfig
from django.http import HttpRequest


class SuperuserAdminSite(admin.AdminSite):
    site_header = "Proficiency testing: administration"
    site_title = "PT administration"

    def has_permission(self, request: HttpRequest) -> bool:
        user = request.user
        return bool(user.is_active and user.is_superuser)


class SuperuserAdminConfig(AdminConfig):
    """Replaces ``django.contrib.admin`` in INSTALLED_APPS (Django's documented way to
    change the default admin site)."""

    default_site = "common.admin_site.SuperuserAdminSite"
