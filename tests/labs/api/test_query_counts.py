"""Database work per API request (bench/README.md, load test): the hot polling endpoints
answer in a fixed, small number of queries, whatever the number of rows behind them."""

import pytest
from auditlog.models import LogEntry
from django.db import connection
from django.test.utils import CaptureQueriesContext

from labs.models import LabAPIKey, Submission
from tests.labs.api import rows

pytestmark = pytest.mark.django_db

SUBMIT = "/api/v1/comparisons/IMU-A-01/submissions/"


def test_key_lookup_brings_its_laboratory_in_the_same_query(world):
    key = world.keys["key_a"]
    with CaptureQueriesContext(connection) as ctx:
        found = LabAPIKey.objects.get_from_key(key)
        lab_name = found.laboratory.name
    assert lab_name == world.lab_a.name
    assert len(ctx.captured_queries) == 1
    assert "labs_laboratory" in ctx.captured_queries[0]["sql"]


def test_revoked_key_is_still_not_usable(world):
    with pytest.raises(LabAPIKey.DoesNotExist):
        LabAPIKey.objects.get_from_key(world.keys["revoked_key_a"])


def _queries(client, path: str) -> tuple[int, int, list[str]]:
    with CaptureQueriesContext(connection) as ctx:
        response = client.get(path)
    return response.status_code, len(ctx.captured_queries), [q["sql"] for q in ctx.captured_queries]


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        # key + laboratory, the page (no COUNT: page 1 holds the whole list)
        ("/api/v1/comparisons/", 2),
        # key + laboratory, participant + comparison, devices, point count
        ("/api/v1/comparisons/{code}/", 4),
        # key + laboratory, participant + comparison, page (n_results annotated; no COUNT)
        ("/api/v1/comparisons/{code}/submissions/", 3),
        # key + laboratory, participant + comparison, the version, its results with points
        ("/api/v1/comparisons/{code}/submissions/1/", 4),
    ],
)
def test_lab_polling_endpoints_query_count(world, path, expected):
    status, n, sql = _queries(world.client("key_a"), path.format(code=world.cmp.code))
    assert status == 200
    assert n == expected, "\n".join(sql)
    # the laboratory is never fetched on its own (it comes with the key)
    assert not any(s.startswith('SELECT "labs_laboratory"') for s in sql)


def _statements(ctx: CaptureQueriesContext) -> list[str]:
    """The captured SQL without transaction control (BEGIN, SAVEPOINT, COMMIT: the
    databases differ) and without the result rows' insert (COPY on PostgreSQL is not
    captured, SQLite's executemany is)."""
    control = ("BEGIN", "SAVEPOINT", "RELEASE", "COMMIT")
    return [
        q["sql"]
        for q in ctx.captured_queries
        if not q["sql"].startswith(control) and 'INSERT INTO "labs_result"' not in q["sql"]
    ]


def test_submission_post_query_count(world):
    """A new submitted version: key + laboratory, participant + comparison, the points
    (once, for the importer and for storing), the participant lock, the latest version,
    the new version stored submitted at once with its one audit entry, and its receipt
    notice (its dedupe key looked up, the notice stored; docs/lifecycles.md §6)."""
    client = world.client("key_a")
    with CaptureQueriesContext(connection) as ctx:
        response = client.post(SUBMIT, {"results": rows()}, format="json")
    assert response.status_code == 201, response.content
    body = response.json()
    assert (body["status"], body["n_results"]) == ("submitted", len(rows()))
    sql = _statements(ctx)
    assert len(sql) == 9, "\n".join(sql)
    assert sum('FROM "proficiency_measurementpoint"' in s for s in sql) == 1
    assert not any(s.startswith("UPDATE") for s in sql)  # no draft step, no second save
    submission = Submission.objects.get(
        participant__laboratory=world.lab_a, version=body["version"]
    )
    assert submission.results.count() == len(rows())
    entries = LogEntry.objects.get_for_object(submission)
    assert [(e.action, e.changes_dict["status"][1]) for e in entries] == [
        (LogEntry.Action.CREATE, "submitted")
    ]


def test_draft_replaced_then_submitted_keeps_no_old_rows(world):
    """A draft's rows are deleted with one statement when it is replaced; the draft then
    becomes the submitted version (same version number, audit: create, update)."""
    client = world.client("key_a")
    first = client.post(SUBMIT, {"results": rows(axes=("X",)), "submit": False}, format="json")
    draft = Submission.objects.get(
        participant__laboratory=world.lab_a, version=first.json()["version"]
    )
    with CaptureQueriesContext(connection) as ctx:
        final = client.post(SUBMIT, {"results": rows()}, format="json")
    assert (final.status_code, final.json()["version"]) == (201, draft.version)
    sql = _statements(ctx)
    deletes = [s for s in sql if s.startswith("DELETE")]
    # no collector: the old rows and their (impossible) scores are not read first
    assert not any(
        'FROM "labs_result"' in s or "analysis_score" in s for s in sql if s.startswith("SELECT")
    )
    assert len(deletes) == 1 and deletes[0].startswith('DELETE FROM "labs_result"'), deletes
    draft.refresh_from_db()
    assert draft.status == Submission.Status.SUBMITTED
    assert draft.results.count() == len(rows())
    assert set(draft.results.values_list("measurement_point__axis", flat=True)) == {
        p.axis for p in world.cmp.measurement_points.all()
    }


def test_version_detail_counts_its_results_from_the_list(world):
    """n_results of one version is the length of its listed results: no COUNT join."""
    status, n, sql = _queries(world.client("key_a"), f"{SUBMIT}1/")
    assert (status, n) == (200, 4)
    assert not any("COUNT(" in s for s in sql), "\n".join(sql)
    body = world.client("key_a").get(f"{SUBMIT}1/").json()
    assert body["n_results"] == len(body["results"]) > 0
