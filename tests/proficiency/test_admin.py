"""Every model has an admin with list filters and search, and the demo shows in it."""

from io import StringIO

import pytest
from django.contrib import admin
from django.core.management import call_command
from django.urls import reverse

from tests.factories import UserFactory

pytestmark = pytest.mark.django_db
OUR_APPS = {"proficiency", "labs", "analysis"}


def our_admins():
    return [(m, a) for m, a in admin.site._registry.items() if m._meta.app_label in OUR_APPS]


def test_every_model_of_ours_is_registered_with_filters_and_search():
    from django.apps import apps

    models = {m for app in OUR_APPS for m in apps.get_app_config(app).get_models()}
    registered = {m for m, _ in our_admins()}
    assert models == registered
    for model, model_admin in our_admins():
        assert model_admin.list_filter, model.__name__
        assert model_admin.search_fields, model.__name__


def test_admin_shows_the_demo(client):
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    client.force_login(UserFactory.create(username="root", is_staff=True, is_superuser=True))
    for model, _ in our_admins():
        url = reverse(f"admin:{model._meta.app_label}_{model._meta.model_name}_changelist")
        assert client.get(url).status_code == 200, url
        assert client.get(url, {"q": "MEMS"}).status_code == 200, url
    body = client.get(reverse("admin:proficiency_comparison_changelist")).content.decode()
    assert "IMU-2024-DEMO" in body
    devices = client.get(reverse("admin:proficiency_device_changelist")).content.decode()
    assert all(f"MEMS {i}" in devices for i in (1, 2, 3))
    points = client.get(reverse("admin:proficiency_measurementpoint_changelist")).content.decode()
    assert "108 measurement points" in points  # 81 of IMU-2024-DEMO, 27 of the open call
    results = client.get(reverse("admin:labs_result_changelist")).content.decode()
    assert "891 results" in results
    participants = client.get(reverse("admin:labs_participant_changelist")).content.decode()
    assert "12 participants" in participants
