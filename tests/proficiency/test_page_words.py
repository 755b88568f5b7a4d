"""The words people read on the pages and in the API's documentation: counts without
"(s)", links where a code is named, messages that fit the reader, method names not ids."""

from __future__ import annotations

import datetime as dt
import re
from typing import cast

import pytest
import yaml
from django import forms
from django.core.management import call_command
from django.utils import timezone

from analysis.forms import ScoreFilterForm
from analysis.models import AnalysisRun, AssignedValue, method_label
from common.sizes import counted
from labs.services import participant_add
from proficiency.models import CODE_INVALID, ComparisonStatus
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MeasurementPointFactory,
    MembershipFactory,
    UserFactory,
)

pytestmark = pytest.mark.django_db


def test_counted_says_one_and_many():
    assert counted(1, "measurement point") == "1 measurement point"
    assert counted(0, "measurement point") == "0 measurement points"
    assert counted(2, "laboratory", "laboratories") == "2 laboratories"
    assert counted(1, "laboratory", "laboratories") == "1 laboratory"


def test_the_api_root_points_to_its_documentation(client):
    response = client.get("/api/v1/")
    assert response.status_code == 200
    assert response.json() == {
        "version": "v1",
        "docs": "http://testserver/api/docs/",
        "schema": "http://testserver/api/schema/",
    }
    assert client.post("/api/v1/").status_code == 405
    # and every page's footer links to the documentation
    home = client.get("/").content
    assert home.count(b'href="/api/docs/">API documentation</a>') == 1


def test_every_operation_has_a_tag_and_run_parameters_are_typed(tmp_path):
    out = tmp_path / "schema.yaml"
    call_command("spectacular", "--file", str(out))
    schema = yaml.safe_load(out.read_text())
    tags = {
        (method, path): op.get("tags")
        for path, ops in schema["paths"].items()
        for method, op in ops.items()
    }
    assert all(t and t != ["v1"] for t in tags.values()), [
        k for k, t in tags.items() if t == ["v1"]
    ]
    assert tags["post", "/api/v1/comparisons/{code}/participants/"] == [
        "round set-up (coordinators)"
    ]
    assert tags["get", "/api/v1/comparisons/{code}/doe-covariance/"] == ["scores and compatibility"]
    assert tags["post", "/api/v1/comparisons/{code}/publish/"] == [
        "round life cycle (coordinators)"
    ]
    parameters = schema["components"]["schemas"]["AnalysisRun"]["properties"]["parameters"]
    assert parameters["allOf"] == [{"$ref": "#/components/schemas/RunParameters"}]
    fields = schema["components"]["schemas"]["RunParameters"]["properties"]
    assert set(fields) == {
        "assigned_value_method",
        "sigma_pt_mode",
        "sigma_pt_value",
        "en_limit",
        "compare",
        "drift_treatment",  # a round with kits: corrected or u_stab (docs/domain.md §13)
    }


def test_the_coordinators_home_links_each_code(client):
    comparison = ComparisonFactory.create(code="LINK-01")
    user = UserFactory.create()
    comparison.coordinators.add(user)
    client.force_login(user)
    assert b'href="/coordinator/LINK-01/">LINK-01</a>' in client.get("/").content


def test_my_comparisons_speaks_to_a_coordinator_as_one(client):
    comparison = ComparisonFactory.create()
    user = UserFactory.create()
    comparison.coordinators.add(user)
    client.force_login(user)
    body = client.get("/lab/").content.decode()
    assert "Your laboratory does not take part" not in body
    assert "The rounds you coordinate are on the" in body
    member = MembershipFactory.create()
    client.force_login(member.user)
    assert "Your laboratory does not take part" in client.get("/lab/").content.decode()


def test_a_bad_comparison_code_is_explained_in_words(client):
    user = UserFactory.create(is_superuser=True)
    client.force_login(user)
    response = client.post(
        "/api/v1/comparisons/", {"code": "IMU 2024", "title": "t"}, content_type="application/json"
    )
    assert response.status_code == 400
    assert CODE_INVALID in str(response.json())
    assert "slug" not in str(response.json())
    page = client.post("/coordinator/new/", {"code": "IMU 2024", "title": "t"}).content.decode()
    assert "slug" not in page
    assert "letters, digits, hyphens and underscores" in page


def test_score_filters_offer_only_the_rounds_levels():
    comparison = ComparisonFactory.create()
    device = DeviceFactory.create(comparison=comparison)
    MeasurementPointFactory.create(
        comparison=comparison, device=device, axis="Z", bench="linear", direction="vertical"
    )
    form = ScoreFilterForm({}, comparison=comparison, lab_codes=[])

    def offered(name: str) -> list[str]:
        choices = cast(list[tuple[str, str]], cast(forms.ChoiceField, form.fields[name]).choices)
        return [v for v, _ in choices]

    assert (offered("bench"), offered("axis"), offered("direction")) == (
        ["", "linear"], ["", "Z"], ["", "vertical"],
    )  # fmt: skip
    assert not ScoreFilterForm(
        {"bench": "curvilinear"}, comparison=comparison, lab_codes=[]
    ).is_valid()


def test_a_published_round_leads_with_its_results_not_a_warning(client):
    comparison = ComparisonFactory.create(
        status=ComparisonStatus.PUBLISHED, submission_deadline=timezone.now() - dt.timedelta(days=3)
    )
    member = MembershipFactory.create()
    participant_add(comparison=comparison, laboratory=member.laboratory)
    client.force_login(member.user)
    body = client.get(f"/lab/comparisons/{comparison.code}/").content.decode()
    assert "Results cannot be saved or submitted now" not in body
    assert "The results of this round are published" in body


def test_the_results_page_names_the_method():
    assert (
        method_label("weighted_mean") == "Weighted mean (largest consistent subset if inconsistent)"
    )
    assert method_label("median_made") == "Median with MADe"
    comparison = ComparisonFactory.create()
    point = MeasurementPointFactory.create(
        comparison=comparison, device=DeviceFactory.create(comparison=comparison)
    )
    run = AnalysisRun.objects.create(comparison=comparison)
    row = AssignedValue.objects.create(
        run=run, measurement_point=point, value=1.0, standard_uncertainty=0.1, method="algorithm_a"
    )
    assert row.method_name == "Robust consensus (ISO 13528 Algorithm A)"


def test_an_invitation_message_counts_in_words(client):
    comparison = ComparisonFactory.create()
    user = UserFactory.create()
    comparison.coordinators.add(user)
    labs = [LaboratoryFactory.create() for _ in range(2)]
    client.force_login(user)
    response = client.post(
        f"/coordinator/{comparison.code}/participants/invite/",
        {"laboratories": [lab.pk for lab in labs]},
        follow=True,
    )
    assert re.search(r"2 laboratories invited: [A-Z0-9]+, [A-Z0-9]+\.", response.content.decode())
