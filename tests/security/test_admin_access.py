"""The admin is for superusers only: a staff coordinator holding every model permission
(as demo databases gave the ``coordinators`` group before) is sent to the admin login on
every admin route, GET and POST, and cannot add an API key for another laboratory.

The permission matrix (test_permission_matrix.py) probes the admin with the personas of
the security world, who are not staff; this test gives them the staff flag and all the
permissions of our apps, the strongest account short of a superuser.
"""

from __future__ import annotations

from io import StringIO

import pytest
from django.contrib.auth.models import Permission
from django.core.management import call_command
from django.test import Client
from django.urls import reverse

from labs.models import LabAPIKey, Laboratory, Participant
from tests.factories import UserFactory
from tests.security.routes import discover
from tests.security.test_permission_matrix import _admin_url
from tests.security.world import LAB_A_NAME

pytestmark = pytest.mark.django_db


def _all_permissions(user):
    user.user_permissions.set(
        Permission.objects.filter(content_type__app_label__in=["proficiency", "labs", "analysis"])
    )
    user.is_staff = True
    user.save(update_fields=["is_staff"])
    return user


def test_a_staff_coordinator_with_every_permission_is_refused_everywhere_in_the_admin(world):
    coordinator = _all_permissions(world.users["coord2"])
    client = Client()
    client.force_login(coordinator)
    login = reverse("admin:login")
    checked = 0
    for route in discover():
        if not route.route.startswith("admin/") or route.name in ("admin:login", "admin:logout"):
            continue
        url = _admin_url(route, world)
        for method in ("get", "post"):
            response = getattr(client, method)(url)
            assert response.status_code == 302, (method, url, response.status_code)
            assert response["Location"].startswith(login), (method, url, response["Location"])
            assert LAB_A_NAME.encode() not in response.content
            checked += 1
    assert checked > 100  # every model's changelist, add, change, delete, history


def test_the_admin_back_door_of_the_attack_is_closed(world):
    """The attack: search participants by code for the laboratory name, add an API key
    for another laboratory, read its submissions through the API with it."""
    coordinator = _all_permissions(world.users["coord2"])
    client = Client()
    client.force_login(coordinator)
    search = client.get(reverse("admin:labs_participant_changelist"), {"q": "QZ7X"})
    assert search.status_code == 302
    keys_before = LabAPIKey.objects.count()
    add = client.post(
        reverse("admin:labs_labapikey_add"),
        {"name": "stolen", "laboratory": world.lab_a.pk},
    )
    assert add.status_code == 302 and add["Location"].startswith(reverse("admin:login"))
    assert LabAPIKey.objects.count() == keys_before
    assert not LabAPIKey.objects.filter(name="stolen").exists()


def test_the_admin_login_does_not_let_staff_in():
    user = UserFactory.create(username="staffer", is_staff=True)
    user.set_password("a long staff password")
    user.save()
    _all_permissions(user)
    client = Client()
    response = client.post(
        reverse("admin:login"),
        {"username": "staffer", "password": "a long staff password", "next": "/admin/"},
        follow=True,
    )
    # signed in, but the admin answers with its login page and the "not authorized" note
    assert response.redirect_chain[-1][0].startswith(reverse("admin:login"))
    assert b"not authorized to access this page" in response.content
    assert client.get(reverse("admin:labs_laboratory_changelist")).status_code == 302


def test_a_superuser_uses_the_admin(world):
    client = Client()
    client.force_login(world.users["superuser"])
    body = client.get(reverse("admin:labs_participant_changelist"), {"q": "QZ7X"})
    assert body.status_code == 200
    assert LAB_A_NAME.encode() in body.content
    assert Laboratory.objects.filter(name=LAB_A_NAME).exists()
    assert Participant.objects.filter(code="QZ7X").exists()


def test_the_demo_coordinator_is_refused_by_the_admin():
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    client = Client()
    signed_in = client.post(
        reverse("login"), {"username": "coordinator", "password": "demo-password-1"}
    )
    assert signed_in.status_code == 302  # to the coordinator's home
    response = client.get(reverse("admin:labs_participant_changelist"))
    assert response.status_code == 302
    assert response["Location"].startswith(reverse("admin:login"))


def test_the_superuser_cannot_edit_what_the_services_record(world):
    """Submissions, results, participants, runs, scores and reports are shown, not edited,
    in the admin (an edit would bypass the state machine and the audit log), and a
    comparison's status changes only by its transitions."""
    client = Client()
    client.force_login(world.users["superuser"])
    result = world.result_a
    submission = result.submission
    change = reverse("admin:labs_submission_change", args=[submission.pk])
    page = client.get(change)
    assert page.status_code == 200 and b'name="_save"' not in page.content
    posted = client.post(change, {"status": "draft", "version": submission.version})
    assert posted.status_code == 403
    submission.refresh_from_db()
    assert submission.status == "accepted"
    edit = client.post(reverse("admin:labs_result_change", args=[result.pk]), {"value": "1"})
    assert edit.status_code == 403
    result.refresh_from_db()
    assert result.value != 1.0
    for name in ("labs_submission", "labs_result", "labs_participant", "analysis_analysisrun",
                 "analysis_score", "analysis_report"):  # fmt: skip
        assert client.get(reverse(f"admin:{name}_add")).status_code == 403, name
        assert client.get(reverse(f"admin:{name}_changelist")).status_code == 200, name
    comparison = world.c1
    form = client.get(reverse("admin:proficiency_comparison_change", args=[comparison.pk]))
    assert form.status_code == 200 and b'name="status"' not in form.content
