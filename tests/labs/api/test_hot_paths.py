"""The API's hot read paths (bench/README.md, "Load test") answer exactly what the DRF
serializers answer, and their per-request lookups still see every change at once:
a key revoked, or a laboratory removed from a comparison, stops working on the next
request (nothing is cached between requests)."""

from __future__ import annotations

import datetime as dt

import pytest
from django.core.exceptions import ImproperlyConfigured
from django.db import connection
from django.test.utils import CaptureQueriesContext
from django.utils import timezone
from rest_framework import serializers
from rest_framework.renderers import JSONRenderer

from common.errors import NotVisible
from common.rendering import ValuesRendering
from labs.access import (
    ComparisonAccess,
    measurement_points,
    submission_results,
    submissions_in_scope,
)
from labs.api import serializers as s
from labs.api.views import ComparisonList, MeasurandList, SubmissionCollection
from labs.models import LabAPIKey, Participant, Submission
from labs.selectors import participant_for_lab, point_unit_expression, scope_flag
from labs.services import api_key_revoke, submission_from_records
from proficiency.models import Comparison, Device
from tests.labs.api import build_world, rows

pytestmark = pytest.mark.django_db

render = JSONRenderer().render


@pytest.fixture
def world():
    w = build_world()
    # a second, decided version with notes, a dof and a NULL amplitude: every column kind
    submission_from_records(
        participant=w.part_a,
        records=rows(419.25, "2%", dof=12, note='re-run after "fixture" change ✓'),
        source="api",
        user=None,
        submit=True,
    )
    Submission.objects.filter(participant=w.part_a, version=1).update(
        status="rejected", decided_at=timezone.now(), message="Units <b>wrong</b>"
    )
    Submission.objects.create(participant=w.part_a, version=3, source="web")  # empty draft
    return w


def _access(w, coordinator: bool) -> ComparisonAccess:
    part = Participant.objects.select_related("comparison").get(pk=w.part_a.pk)
    return ComparisonAccess(part.comparison, None if coordinator else part, coordinator)


@pytest.mark.parametrize("coordinator", [False, True])
def test_history_rows_equal_the_serializer(world, coordinator):
    qs = submissions_in_scope(_access(world, coordinator))
    expected = s.SubmissionSerializer(qs, many=True).data
    assert len(expected) == 3
    assert render(SubmissionCollection.rendering.data(qs)) == render(expected)


def test_results_rows_equal_the_serializer(world):
    for submission in Submission.objects.filter(participant=world.part_a):
        qs = submission_results(submission)
        expected = s.ResultSerializer(qs, many=True).data
        assert render(s.RESULT_ROWS.data(qs)) == render(expected)
    # the second version really has the awkward values
    second = s.RESULT_ROWS.data(submission_results(world.part_a.submissions.get(version=2)))
    assert second[0]["dof"] == 12.0 and second[0]["note"].endswith("✓")
    assert second[0]["amplitude_m_s2"] is None
    assert second[0]["expanded_uncertainty"] == pytest.approx(419.25 * 0.02)


def test_measurands_and_comparisons_equal_the_serializer(world):
    qs = measurement_points(world.cmp).annotate(
        in_scope=scope_flag(world.part_a), point_unit=point_unit_expression()
    )  # the view's queryset
    assert len(qs) == 4 and all(p.in_scope for p in qs)
    expected = s.MeasurementPointSerializer(qs, many=True).data
    assert render(MeasurandList.rendering.data(qs)) == render(expected)
    comparisons = Comparison.objects.order_by("-created_at", "code")
    expected = s.ComparisonSerializer(comparisons, many=True).data
    assert render(ComparisonList.rendering.data(comparisons)) == render(expected)


@pytest.mark.parametrize("coordinator", [False, True])
def test_comparison_detail_equals_the_serializer(world, coordinator):
    Device.objects.create(comparison=world.cmp, name="MEMS 0", model="X", serial="S0",
                          nominal_sensitivity=100.0, tolerance=2.0)  # fmt: skip
    access = _access(world, coordinator)
    expected = s.ComparisonDetailSerializer(access.comparison, context={"access": access}).data
    assert [d["name"] for d in expected["devices"]] == ["MEMS 0", "MEMS 1"]
    assert render(s.comparison_detail_data(access.comparison, access)) == render(expected)


def test_submission_detail_equals_the_serializer(world):
    access = _access(world, coordinator=False)
    for submission in submissions_in_scope(access):
        results = submission_results(submission)
        expected = s.SubmissionDetailSerializer(submission, context={"results": results}).data
        assert render(s.submission_detail_data(submission, results)) == render(expected)


def test_api_answers_are_the_serializer_answers(world):
    """End to end through the views: the JSON bodies, byte for byte."""
    client = world.client("key_a")
    code = world.cmp.code
    access = _access(world, coordinator=False)
    body = client.get(f"/api/v1/comparisons/{code}/submissions/2/").content
    sub = submissions_in_scope(access).get(version=2)
    expected = s.SubmissionDetailSerializer(sub, context={"results": submission_results(sub)})
    assert body == render(expected.data)
    body = client.get(f"/api/v1/comparisons/{code}/").content
    detail = s.ComparisonDetailSerializer(access.comparison, context={"access": access})
    assert body == render(detail.data)
    page = client.get(f"/api/v1/comparisons/{code}/submissions/").json()
    assert page["count"] == 3 and page["next"] is None and page["previous"] is None
    assert [r["version"] for r in page["results"]] == [3, 2, 1]
    assert [r["n_results"] for r in page["results"]] == [0, 4, 4]


def test_rendering_refuses_what_it_cannot_reproduce():
    class Method(serializers.ModelSerializer):
        x = serializers.SerializerMethodField()

        class Meta:
            model = Device
            fields = ["name", "x"]

    class Nullable(serializers.ModelSerializer):
        who = serializers.CharField(source="submitted_by.username")

        class Meta:
            model = Submission
            fields = ["who"]

    class Relation(serializers.ModelSerializer):
        class Meta:
            model = Device
            fields = ["comparison"]

    for cls in (Method, Nullable, Relation):
        with pytest.raises(ImproperlyConfigured):
            ValuesRendering(cls).plan()
    with pytest.raises(ImproperlyConfigured):
        ValuesRendering(s.ComparisonDetailSerializer, computed=["devices"]).plan()


# -- the per-request lookups: read at every request, nothing kept between requests ---------


def test_key_lookup_is_one_query_with_converted_values(world):
    key = world.keys["key_a"]
    with CaptureQueriesContext(connection) as ctx:
        found = LabAPIKey.objects.get_from_key(key)
    assert len(ctx.captured_queries) == 1
    stored = LabAPIKey.objects.select_related("laboratory").get(pk=found.pk)
    assert (found.pk, found.prefix, found.name, found.revoked) == (
        stored.pk, stored.prefix, stored.name, False)  # fmt: skip
    assert found.created == stored.created and found.created.tzinfo is not None
    assert found.laboratory == world.lab_a and found.laboratory.name == world.lab_a.name
    assert found.laboratory.created_at == stored.laboratory.created_at
    with pytest.raises(LabAPIKey.DoesNotExist):
        LabAPIKey.objects.get_from_key(key[:-1] + ("A" if key[-1] != "A" else "B"))
    with pytest.raises(LabAPIKey.DoesNotExist):
        LabAPIKey.objects.get_from_key(world.keys["revoked_key_a"])


def test_revoking_a_key_stops_it_on_the_next_request(world):
    client = world.client("key_a")
    url = f"/api/v1/comparisons/{world.cmp.code}/"
    assert client.get(url).status_code == 200
    assert client.get(url).status_code == 200
    api_key_revoke(key=LabAPIKey.objects.get_from_key(world.keys["key_a"]))
    response = client.get(url)
    assert response.status_code == 401
    assert "revoked" in response.json()["detail"]


def test_bulk_revocation_and_expiry_stop_a_key_on_the_next_request(world):
    client = world.client("key_a")
    assert client.get("/api/v1/comparisons/").status_code == 200
    LabAPIKey.objects.filter(laboratory=world.lab_a).update(
        expiry_date=timezone.now() - dt.timedelta(minutes=1)
    )  # no signal, no save(): nothing to invalidate, the next lookup reads it
    assert client.get("/api/v1/comparisons/").status_code == 401
    LabAPIKey.objects.filter(laboratory=world.lab_a).update(expiry_date=None, revoked=True)
    assert client.get("/api/v1/comparisons/").status_code == 401


def test_removed_participation_is_404_on_the_next_request(world):
    client = world.client("key_a")
    url = f"/api/v1/comparisons/{world.shared.code}/"
    assert client.get(url).json()["participant_code"] == "L71"
    Participant.objects.filter(pk=world.shared_a.pk).delete()
    assert client.get(url).status_code == 404
    assert client.get(f"/api/v1/comparisons/{world.shared.code}/submissions/").status_code == 404


def test_participant_lookup_values(world):
    found = participant_for_lab(code=world.cmp.code, laboratory=world.lab_a)
    stored = Participant.objects.select_related("comparison").get(pk=world.part_a.pk)
    assert (found.pk, found.code, found.is_reference, found.invited_at) == (
        stored.pk, stored.code, stored.is_reference, stored.invited_at)  # fmt: skip
    c, sc = found.comparison, stored.comparison
    assert (c.pk, c.code, c.status, c.submission_deadline, c.created_at) == (
        sc.pk, sc.code, sc.status, sc.submission_deadline, sc.created_at)  # fmt: skip
    assert c.submission_deadline is not None and c.submission_deadline.tzinfo is not None
    assert found.laboratory is world.lab_a
    with pytest.raises(NotVisible):
        participant_for_lab(code=world.other.code, laboratory=world.lab_a)
    with pytest.raises(NotVisible):
        participant_for_lab(code="NO-SUCH", laboratory=world.lab_a)


@pytest.mark.parametrize("submit", [False, True])
def test_posted_version_reports_its_stored_result_count_without_counting(world, submit):
    client = world.client("key_a")
    url = f"/api/v1/comparisons/{world.cmp.code}/submissions/"
    # a draft first (3 rows), then the same draft replaced or submitted with 4 rows
    first = client.post(url, {"results": rows(axes=("X",))[:1] + rows(axes=("Y",)),
                              "submit": False}, format="json")  # fmt: skip
    assert first.status_code == 201 and first.json()["n_results"] == 3
    with CaptureQueriesContext(connection) as ctx:
        second = client.post(url, {"results": rows(), "submit": submit}, format="json")
    body = second.json()
    assert second.status_code == 201
    assert body["version"] == first.json()["version"]  # the same draft, replaced
    stored = Submission.objects.get(participant=world.part_a, version=body["version"])
    assert body["n_results"] == stored.results.count() == 4
    assert body["status"] == ("submitted" if submit else "draft")
    assert not any(q["sql"].upper().startswith("SELECT COUNT(*)") for q in ctx.captured_queries)
