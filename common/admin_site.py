"""The Django admin is for superusers only.

Coordinators run their rounds through the coordinator pages and API, which scope every
query to the comparisons they coordinate. The admin cannot be scoped that way (it lists
every laboratory behind its code, every round's results, every API key), so it is closed
to everyone but superusers, whatever their staff flag or model permissions say.
"""

from django.contrib import admin
from django.contrib.admin.apps import AdminConfig
from django.db.models import Model
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


class ViewOnly:
    """An admin (or inline) that shows rows but cannot add or change them."""

    def has_add_permission(self, request: HttpRequest, obj: Model | None = None) -> bool:
        return False

    def has_change_permission(self, request: HttpRequest, obj: Model | None = None) -> bool:
        return False


class RecordedByServicesAdmin(ViewOnly, admin.ModelAdmin):
    """Rows the services write and the rest of the service relies on (submissions and
    their results, analysis runs and their outputs, reports): the admin shows them but
    cannot add or change them, because an edit here would bypass the state machine, the
    audit log and the invariants the runs rely on (a submitted or accepted version's
    results never change; a published run's scores are what was published).  Decisions
    are made on the coordinator's pages and through the API; deleting stays possible."""
