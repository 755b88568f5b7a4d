"""API key pages: managers only; a new key is shown once, is valid, and can be revoked."""

import re

import pytest
from django.urls import reverse

from labs.models import LabAPIKey, Membership
from labs.services import api_key_create
from tests.factories import LaboratoryFactory, MembershipFactory
from tests.labs.test_web import visible

pytestmark = pytest.mark.django_db


@pytest.fixture
def manager():
    return MembershipFactory.create(role=Membership.Role.MANAGER)


@pytest.fixture
def keys_url(manager):
    return reverse("labs:api_keys", args=[manager.laboratory_id])


def test_create_shows_the_key_once_and_it_authenticates(client, manager, keys_url):
    client.force_login(manager.user)
    response = client.post(keys_url, {"name": "calibration PC"})
    assert response.status_code == 200
    assert "no-cache" in response["Cache-Control"] or "no-store" in response["Cache-Control"]
    body = visible(response)
    shown = re.search(r'id="api-key" class="[^"]*" type="text" value="([^"]+)"', body)
    assert shown is not None, body
    key = shown.group(1)
    assert LabAPIKey.objects.is_valid(key)
    key_obj = LabAPIKey.objects.get_from_key(key)
    assert key_obj.laboratory == manager.laboratory and key_obj.created_by == manager.user
    assert 'id="copy-key"' in body and "shown only on this page" in body
    listing = visible(client.get(keys_url))
    assert "calibration PC" in listing and key_obj.prefix in listing and key not in listing


def test_empty_name_is_refused(client, manager, keys_url):
    client.force_login(manager.user)
    response = client.post(keys_url, {"name": "   "})
    assert response.status_code == 200 and "is-invalid" in visible(response)
    assert not LabAPIKey.objects.exists()


def test_revoke_asks_then_revokes(client, manager, keys_url):
    key_obj, key = api_key_create(laboratory=manager.laboratory, name="old", user=None)
    client.force_login(manager.user)
    url = reverse("labs:api_key_revoke", args=[manager.laboratory_id, key_obj.prefix])
    assert "Revoke the key" in visible(client.get(url))
    assert LabAPIKey.objects.is_valid(key)
    response = client.post(url)
    assert response.status_code == 302 and response["Location"] == keys_url
    assert not LabAPIKey.objects.is_valid(key)
    assert "Revoked" in visible(client.get(keys_url))


def test_other_labs_manager_cannot_touch_the_keys(client, manager):
    key_obj, key = api_key_create(laboratory=manager.laboratory, name="mine", user=None)
    other = MembershipFactory.create(
        laboratory=LaboratoryFactory.create(), role=Membership.Role.MANAGER
    )
    client.force_login(other.user)
    lab_pk = manager.laboratory_id
    revoke = reverse("labs:api_key_revoke", args=[lab_pk, key_obj.prefix])
    assert client.get(reverse("labs:api_keys", args=[lab_pk])).status_code == 404
    assert client.post(revoke).status_code == 404
    # a key of another lab is not found through one's own lab either
    own_revoke = reverse("labs:api_key_revoke", args=[other.laboratory_id, key_obj.prefix])
    assert client.post(own_revoke).status_code == 404
    assert LabAPIKey.objects.is_valid(key)


def test_staff_cannot_create_or_revoke(client, manager):
    key_obj, key = api_key_create(laboratory=manager.laboratory, name="mine", user=None)
    staff = MembershipFactory.create(laboratory=manager.laboratory)
    client.force_login(staff.user)
    lab_pk = manager.laboratory_id
    assert client.post(reverse("labs:api_keys", args=[lab_pk]), {"name": "x"}).status_code == 404
    revoke = reverse("labs:api_key_revoke", args=[lab_pk, key_obj.prefix])
    assert client.post(revoke).status_code == 404
    assert LabAPIKey.objects.filter(laboratory=manager.laboratory).count() == 1
    assert LabAPIKey.objects.is_valid(key)
