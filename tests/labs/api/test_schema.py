"""The OpenAPI schema documents the promised paths and the error shape; docs work offline."""

import io

import pytest
import yaml
from django.core.management import call_command
from rest_framework.test import APIClient

pytestmark = pytest.mark.django_db

PROMISED = {
    "/api/v1/comparisons/": {"get"},
    "/api/v1/comparisons/{code}/": {"get"},
    "/api/v1/comparisons/{code}/measurands/": {"get"},
    "/api/v1/comparisons/{code}/template.csv": {"get"},
    "/api/v1/comparisons/{code}/submissions/": {"get", "post"},
    "/api/v1/comparisons/{code}/submissions/upload/": {"post"},
    "/api/v1/comparisons/{code}/submissions/{version}/": {"get"},
}


def test_schema_validates_without_warnings(tmp_path):
    target = tmp_path / "schema.yaml"
    call_command("spectacular", "--validate", "--fail-on-warn", "--file", str(target))
    schema = yaml.safe_load(target.read_text())
    for path, methods in PROMISED.items():
        assert methods <= set(schema["paths"][path]), path


def test_schema_is_served_with_the_error_shape_and_key_scheme():
    response = APIClient().get("/api/schema/?format=json")
    assert response.status_code == 200
    schema = response.json()
    assert PROMISED.keys() <= schema["paths"].keys()
    error = schema["components"]["schemas"]["Error"]
    assert set(error["properties"]) == {"detail", "errors"}
    assert schema["components"]["securitySchemes"]["labApiKey"]["name"] == "Authorization"
    post = schema["paths"]["/api/v1/comparisons/{code}/submissions/"]["post"]
    assert {"201", "400", "401", "403", "404", "409", "413", "429"} <= post["responses"].keys()
    upload = schema["paths"]["/api/v1/comparisons/{code}/submissions/upload/"]["post"]
    assert "multipart/form-data" in upload["requestBody"]["content"]


def test_swagger_ui_is_served_from_the_sidecar_not_a_cdn():
    response = APIClient().get("/api/docs/")
    assert response.status_code == 200
    html = response.content.decode()
    assert "drf_spectacular_sidecar" in html
    assert "cdn." not in html and "unpkg" not in html


def test_spectacular_command_writes_yaml():
    out = io.StringIO()
    call_command("spectacular", stdout=out)
    assert "/api/v1/comparisons/{code}/submissions/upload/" in out.getvalue()
