"""The admin in the browser, as a staff coordinator holding every model permission (what
demo databases gave the coordinators group before) and as a superuser.

The coordinator is signed in and shown the admin's "not authorized" page on the admin's
index and on the participants list it used to read laboratory names from; the superuser
reads that list. Screenshots in test-artifacts/browser/<test>/.
"""

from __future__ import annotations

import pytest
from django.contrib.auth.models import Permission
from playwright.sync_api import Page, expect

from labs.models import Participant
from tests.factories import ComparisonFactory, LaboratoryFactory, UserFactory

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

PASSWORD = "correct horse battery staple"  # tests.factories.UserFactory's
SECRET_LAB = "Quasar Vibration Laboratory"


def _admin_sign_in(page: Page, base: str, username: str) -> None:
    page.goto(f"{base}/admin/login/?next=/admin/")
    page.get_by_label("Username").fill(username)
    page.get_by_label("Password").fill(PASSWORD)
    page.get_by_role("button", name="Log in").click()


def test_admin_refuses_a_staff_coordinator_and_serves_the_superuser(
    page: Page, new_context, live_server, shots
):
    mine, other = (
        ComparisonFactory.create(code="ADM-MINE"),
        ComparisonFactory.create(code="ADM-OTHER"),
    )
    Participant.objects.create(
        comparison=other, laboratory=LaboratoryFactory.create(name=SECRET_LAB), code="QX9"
    )
    coordinator = UserFactory.create(username="carla", is_staff=True)
    coordinator.user_permissions.set(
        Permission.objects.filter(content_type__app_label__in=["proficiency", "labs", "analysis"])
    )
    mine.coordinators.add(coordinator)
    UserFactory.create(username="root", is_staff=True, is_superuser=True)
    base = live_server.url

    _admin_sign_in(page, base, "carla")
    expect(
        page.get_by_text("You are authenticated as carla, but are not authorized")
    ).to_be_visible()
    shots(page, "admin-coordinator-refused")
    page.goto(f"{base}/admin/labs/participant/?q=QX9")
    expect(page.get_by_text("but are not authorized")).to_be_visible()
    assert SECRET_LAB not in page.content()
    shots(page, "admin-coordinator-participants-refused")

    root = new_context().new_page()
    _admin_sign_in(root, base, "root")
    root.goto(f"{base}/admin/labs/participant/?q=QX9")
    expect(root.get_by_role("link", name="QX9")).to_be_visible()
    expect(root.get_by_text(SECRET_LAB)).to_be_visible()
    shots(root, "admin-superuser-participants")
