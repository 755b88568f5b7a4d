"""API keys (revoked, expired, malformed), throttling, and the create_api_key command."""

import datetime as dt
import io

import pytest
from django.core.management import CommandError, call_command
from django.utils import timezone
from rest_framework.test import APIClient

from labs.models import LabAPIKey

pytestmark = pytest.mark.django_db

LIST = "/api/v1/comparisons/"


def with_header(value: str) -> APIClient:
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION=value)
    return client


def test_revoked_key_is_401_and_says_revoked(world):
    response = world.client("revoked_key_a").get(LIST)
    assert response.status_code == 401
    assert "revoked" in response.json()["detail"]


def test_expired_key_is_401_and_says_when(world):
    key = world.keys["key_a"]
    expiry = timezone.now() - dt.timedelta(days=1)
    LabAPIKey.objects.filter(prefix=key.partition(".")[0]).update(expiry_date=expiry)
    response = world.client("key_a").get(LIST)
    assert response.status_code == 401
    assert f"expired on {expiry:%Y-%m-%d}" in response.json()["detail"]


@pytest.mark.parametrize("header", ["Api-Key nonsense", "Api-Key", "api-key XXXXXXXX.wrongsecret"])
def test_bad_keys_are_401(world, header):
    response = with_header(header).get(LIST)
    assert response.status_code == 401
    assert response.json()["detail"]


def test_wrong_secret_of_a_revoked_prefix_is_not_called_revoked(world):
    prefix = world.keys["revoked_key_a"].partition(".")[0]
    response = with_header(f"Api-Key {prefix}.guessed").get(LIST)
    assert "Invalid API key" in response.json()["detail"]


def test_other_schemes_fall_through_to_401(world):
    assert with_header(f"Bearer {world.keys['key_a']}").get(LIST).status_code == 401


def test_keyword_is_case_insensitive(world):
    assert with_header(f"api-key {world.keys['key_a']}").get(LIST).status_code == 200


def _rates(settings, **rates):
    settings.REST_FRAMEWORK = {
        **settings.REST_FRAMEWORK,
        "DEFAULT_THROTTLE_RATES": {"api_key": "600/min", "user": "600/min", **rates},
    }


def test_key_throttle_gives_429_per_key(settings, world):
    _rates(settings, api_key="2/min")
    client = world.client("key_a")
    assert [client.get(LIST).status_code for _ in range(3)] == [200, 200, 429]
    response = client.get(LIST)
    assert response.status_code == 429 and int(response["Retry-After"]) > 0
    assert set(response.json()) == {"detail", "errors"}
    assert world.client("key_b").get(LIST).status_code == 200  # another key, another bucket
    assert world.client("staff_a").get(LIST).status_code == 200  # people are not keys


def test_user_throttle_gives_429(settings, world):
    _rates(settings, user="2/min")
    client = world.client("staff_a")
    assert [client.get(LIST).status_code for _ in range(3)] == [200, 200, 429]
    assert world.client("staff_b").get(LIST).status_code == 200
    assert world.client("key_a").get(LIST).status_code == 200


def test_create_api_key_prints_a_working_key(world):
    out, err = io.StringIO(), io.StringIO()
    call_command(
        "create_api_key", "--lab", world.lab_b.name, "--name", "robot", stdout=out, stderr=err
    )
    key = out.getvalue().strip()
    assert "cannot be shown again" in err.getvalue()
    api_key = LabAPIKey.objects.get_from_key(key)
    assert (api_key.laboratory, api_key.name) == (world.lab_b, "robot")
    codes = [c["code"] for c in with_header(f"Api-Key {key}").get(LIST).json()["results"]]
    assert sorted(codes) == ["IMU-AB-01", "IMU-B-01"]


def test_create_api_key_by_id(world):
    out = io.StringIO()
    call_command("create_api_key", "--lab", str(world.lab_a.pk), stdout=out, stderr=io.StringIO())
    assert LabAPIKey.objects.get_from_key(out.getvalue().strip()).laboratory == world.lab_a


@pytest.mark.parametrize("args", [["--lab", "No Such Lab"], ["--lab", "999999"]])
def test_create_api_key_unknown_lab(world, args):
    with pytest.raises(CommandError, match="No laboratory"):
        call_command("create_api_key", *args)


def test_create_api_key_needs_a_name(world):
    with pytest.raises(CommandError, match="name"):
        call_command("create_api_key", "--lab", world.lab_a.name, "--name", "  ")
