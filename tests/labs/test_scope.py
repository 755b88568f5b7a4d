"""Participant scopes (docs/domain.md §10): a two-bench round, a linear-only laboratory and a
curvilinear-only one. Each submits complete for its own scope through the web grid, a CSV
upload and the API; a point outside its scope is a row error with nothing stored; a
laboratory without a scope still reports every point; the coordinator sets and changes
scopes (web and API) until the deadline, and only for its own comparisons."""

import datetime as dt

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from django.urls import reverse
from django.utils import timezone
from rest_framework.test import APIClient

from labs.models import Participant, Submission
from labs.selectors import participant_points, scope_text
from labs.services import Scope, api_key_create, participant_scope_set, participants_invite
from proficiency.services import measurement_points_generate
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MembershipFactory,
    UserFactory,
)
from tests.labs.test_web import visible

pytestmark = pytest.mark.django_db

CODE = "IMU-SCOPE"
HEADER = "device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty\r\n"
API = f"/api/v1/comparisons/{CODE}"


class Round:
    """MEMS 1 and MEMS 2, axis X at 5 and 10 Hz on the linear bench (vertical) and the
    curvilinear bench (tangential): 8 points. ``linear`` measures the linear bench of both
    devices (4 points), ``curvilinear`` the curvilinear bench of MEMS 2 (2 points), ``full``
    has no scope (8 points)."""

    def __init__(self) -> None:
        self.coordinator = UserFactory.create(username="coord-scope")
        deadline = timezone.now() + dt.timedelta(days=30)
        self.comparison = ComparisonFactory.create(
            code=CODE, status="open", submission_deadline=deadline
        )
        self.comparison.coordinators.add(self.coordinator)
        self.mems1 = DeviceFactory.create(comparison=self.comparison, name="MEMS 1")
        self.mems2 = DeviceFactory.create(comparison=self.comparison, name="MEMS 2")
        for bench, direction in (("linear", "vertical"), ("curvilinear", "tangential")):
            measurement_points_generate(
                comparison=self.comparison,
                devices=[self.mems1, self.mems2],
                axes=["X"],
                frequencies_hz=[5, 10],
                benches=[bench],
                directions=[direction],
            )
        labs = {n: LaboratoryFactory.create(name=f"Lab {n}") for n in ("lin", "cur", "full")}
        (self.linear,) = participants_invite(
            comparison=self.comparison, laboratories=[labs["lin"]], scope=Scope(benches=["linear"])
        )
        (self.curvilinear,) = participants_invite(
            comparison=self.comparison,
            laboratories=[labs["cur"]],
            scope=Scope(devices=["MEMS 2"], benches=["curvilinear"]),
        )
        (self.full,) = participants_invite(comparison=self.comparison, laboratories=[labs["full"]])

    def staff(self, participant: Participant):
        return MembershipFactory.create(laboratory=participant.laboratory).user

    def api(self, participant: Participant) -> APIClient:
        _, key = api_key_create(laboratory=participant.laboratory, name="bench PC", user=None)
        client = APIClient()
        client.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
        return client


@pytest.fixture
def world() -> Round:
    return Round()


def records(points, value="420.5"):
    return [
        {"device": p.device.name, "axis": p.axis, "frequency_hz": p.frequency_hz,
         "bench": p.bench, "direction": p.direction, "sensitivity": value,
         "expanded_uncertainty": "8.4"}
        for p in points
    ]  # fmt: skip


def csv_of(recs) -> bytes:
    lines = [
        f"{r['device']},{r['axis']},{r['frequency_hz']},{r['bench']},{r['direction']},"
        f"{r['sensitivity']},{r['expanded_uncertainty']}\r\n"
        for r in recs
    ]
    return (HEADER + "".join(lines)).encode()


def labels(participant):
    return [(p.device.name, p.bench, p.frequency_hz) for p in participant_points(participant)]


# --- the scope as data ----------------------------------------------------------------------


def test_participant_points_follow_the_scope(world):
    assert labels(world.linear) == [
        ("MEMS 1", "linear", 5), ("MEMS 1", "linear", 10),
        ("MEMS 2", "linear", 5), ("MEMS 2", "linear", 10),
    ]  # fmt: skip
    assert labels(world.curvilinear) == [
        ("MEMS 2", "curvilinear", 5),
        ("MEMS 2", "curvilinear", 10),
    ]
    assert participant_points(world.full).count() == 8  # no scope: every point
    assert scope_text(world.linear) == "bench linear"
    assert scope_text(world.curvilinear) == "device MEMS 2; bench curvilinear"
    assert scope_text(world.full) == "every measurement point"
    stored = Participant.objects.get(pk=world.curvilinear.pk)
    assert stored.scope_benches == ["curvilinear"]
    assert [d.name for d in stored.scope_devices.all()] == ["MEMS 2"]


def test_an_existing_participant_without_scope_sees_every_point(world):
    """A row as the migration leaves it (empty lists, no device): every point."""
    Participant.objects.filter(pk=world.full.pk).update(
        scope_benches=[], scope_axes=[], scope_frequencies_hz=[]
    )
    assert participant_points(Participant.objects.get(pk=world.full.pk)).count() == 8


def test_scope_values_are_checked_against_the_comparison(world):
    from common.errors import ValidationFailed

    with pytest.raises(ValidationFailed) as exc:
        participant_scope_set(
            participant=world.full,
            scope=Scope(devices=["MEMS 9"], benches=["rotary"], axes=["W"], frequencies_hz=[7]),
        )
    assert [(e["field"], e["message"]) for e in exc.value.errors] == [
        ("devices", f"MEMS 9 is not a device of {CODE}"),
        ("benches", "unknown bench 'rotary'; one of linear, curvilinear, sine_on_random"),
        ("axes", "unknown axis 'W'; one of X, Y, Z"),
        ("frequencies_hz", f"7 Hz is not a frequency of {CODE}"),
    ]
    with pytest.raises(ValidationFailed, match="holds none of the measurement points"):
        participant_scope_set(participant=world.full, scope=Scope(axes=["Y"]))
    assert participant_points(world.full).count() == 8  # nothing changed


# --- submissions ----------------------------------------------------------------------------


def grid_post(points, action="submit"):
    data = {"action": action}
    for i, _ in enumerate(points):
        data |= {f"r{i}-sensitivity": "420.5", f"r{i}-expanded_uncertainty": "8.4",
                 f"r{i}-coverage_factor": "2"}  # fmt: skip
    return data


@pytest.mark.parametrize("who, n", [("linear", 4), ("curvilinear", 2)])
def test_grid_shows_and_submits_the_scope(client, world, who, n):
    participant = getattr(world, who)
    client.force_login(world.staff(participant))
    grid = reverse("labs:grid", args=[CODE])
    body = visible(client.get(grid))
    assert body.count('<tr id="row-') == n
    response = client.post(grid, grid_post(list(participant_points(participant))))
    assert response.status_code == 302
    assert response["Location"] == reverse("labs:comparison", args=[CODE])
    submission = Submission.objects.get(participant=participant)
    assert (submission.status, submission.source) == ("submitted", "web")
    assert sorted(submission.results.values_list("measurement_point_id", flat=True)) == sorted(
        participant_points(participant).values_list("pk", flat=True)
    )


@pytest.mark.parametrize("who", ["linear", "curvilinear"])
def test_csv_upload_of_the_scope_is_complete(client, world, who):
    participant = getattr(world, who)
    client.force_login(world.staff(participant))
    data = csv_of(records(participant_points(participant)))
    response = client.post(
        reverse("labs:upload", args=[CODE]),
        {"file": SimpleUploadedFile("r.csv", data), "action": "submit"},
    )
    assert response.status_code == 302
    submission = Submission.objects.get(participant=participant)
    assert (submission.status, submission.source) == ("submitted", "file")
    assert submission.results.count() == participant_points(participant).count()


def test_csv_upload_outside_the_scope_is_a_row_error(client, world):
    client.force_login(world.staff(world.linear))
    outside = world.comparison.measurement_points.get(
        device=world.mems2, bench="curvilinear", frequency_hz=10
    )
    recs = records(participant_points(world.linear)) + records([outside])
    response = client.post(
        reverse("labs:upload", args=[CODE]),
        {"file": SimpleUploadedFile("r.csv", csv_of(recs)), "action": "submit"},
    )
    assert response.status_code == 200
    body = visible(response)
    assert "The file was not accepted — nothing was stored" in body
    assert (
        '<td data-label="Row" class="text-nowrap">row 6</td>\n'
        '        <td data-label="Column">—</td>\n'
        '        <td data-label="Problem">MEMS 2, X, 10 Hz, curvilinear tangential is not in your '
        "scope (bench linear)</td>"
    ) in body
    assert not Submission.objects.filter(participant=world.linear).exists()


@pytest.mark.parametrize("who", ["linear", "curvilinear"])
def test_api_submission_of_the_scope_is_complete(world, who):
    participant = getattr(world, who)
    client = world.api(participant)
    response = client.post(
        f"{API}/submissions/",
        {"results": records(participant_points(participant))},
        format="json",
    )
    assert response.status_code == 201, response.json()
    body = response.json()
    assert (body["status"], body["source"], body["n_results"]) == (
        "submitted", "api", participant_points(participant).count(),
    )  # fmt: skip
    assert Submission.objects.get(participant=participant).results.count() == body["n_results"]


def test_api_submission_outside_the_scope_is_a_row_error(world):
    client = world.api(world.curvilinear)
    outside = world.comparison.measurement_points.get(
        device=world.mems1, bench="linear", frequency_hz=5
    )
    recs = records(participant_points(world.curvilinear)) + records([outside])
    response = client.post(f"{API}/submissions/", {"results": recs}, format="json")
    assert response.status_code == 400
    assert response.json()["errors"] == [
        {"row": 3, "field": None,
         "message": "MEMS 1, X, 5 Hz, linear vertical is not in your scope "
                    "(device MEMS 2; bench curvilinear)"},
    ]  # fmt: skip
    assert not Submission.objects.filter(participant=world.curvilinear).exists()


def test_api_upload_outside_the_scope_stores_nothing(world):
    client = world.api(world.linear)
    outside = world.comparison.measurement_points.get(
        device=world.mems2, bench="curvilinear", frequency_hz=10
    )
    data = csv_of(records([outside]) + records(participant_points(world.linear)))
    file = SimpleUploadedFile("r.csv", data, content_type="text/csv")
    response = client.post(f"{API}/submissions/upload/", {"file": file}, format="multipart")
    assert response.status_code == 400
    assert response.json()["errors"] == [
        {"row": 2, "field": None,
         "message": "MEMS 2, X, 10 Hz, curvilinear tangential is not in your scope "
                    "(bench linear)"},
    ]  # fmt: skip
    assert not Submission.objects.filter(participant=world.linear).exists()


def test_missing_points_lists_the_scope_only(world):
    client = world.api(world.linear)
    first = list(participant_points(world.linear))[:1]
    response = client.post(f"{API}/submissions/", {"results": records(first)}, format="json")
    assert response.status_code == 400
    body = response.json()
    assert body["detail"] == (
        "3 measurement points of your scope (bench linear) have no result; a partial "
        "submission can only be saved as a draft."
    )
    assert [e["message"] for e in body["errors"]] == [
        "missing result for MEMS 1, X, 10 Hz, linear vertical",
        "missing result for MEMS 2, X, 5 Hz, linear vertical",
        "missing result for MEMS 2, X, 10 Hz, linear vertical",
    ]
    assert not Submission.objects.filter(participant=world.linear).exists()


def test_a_laboratory_without_scope_still_reports_every_point(world):
    client = world.api(world.full)
    linear = [p for p in participant_points(world.full) if p.bench == "linear"]
    response = client.post(f"{API}/submissions/", {"results": records(linear)}, format="json")
    assert response.status_code == 400
    assert response.json()["detail"].startswith("4 measurement points have no result;")
    everything = records(participant_points(world.full))
    response = client.post(f"{API}/submissions/", {"results": everything}, format="json")
    assert response.status_code == 201
    assert Submission.objects.get(participant=world.full).results.count() == 8


@pytest.mark.parametrize("path", ["labs:template", "api"])
def test_template_lists_the_scope(client, world, path):
    if path == "api":
        response = world.api(world.curvilinear).get(f"{API}/template.csv")
    else:
        client.force_login(world.staff(world.curvilinear))
        response = client.get(reverse("labs:template", args=[CODE, "csv"]))
    assert response.status_code == 200
    lines = response.content.decode("utf-8-sig").splitlines()
    assert [line.split(",")[:5] for line in lines[1:]] == [
        ["MEMS 2", "X", "5.0", "curvilinear", "tangential"],
        ["MEMS 2", "X", "10.0", "curvilinear", "tangential"],
    ]


def test_comparison_page_shows_the_scope(client, world):
    client.force_login(world.staff(world.linear))
    body = visible(client.get(reverse("labs:comparison", args=[CODE])))
    assert "Bench linear (4 of 8 measurement points)" in body
    assert "curvilinear" not in body.split("Your measurement points")[1]


# --- the coordinator ------------------------------------------------------------------------


def test_review_counts_completeness_against_each_scope(client, world):
    for participant in (world.linear, world.curvilinear):
        response = world.api(participant).post(
            f"{API}/submissions/", {"results": records(participant_points(participant))},
            format="json",
        )  # fmt: skip
        assert response.status_code == 201
    client.force_login(world.coordinator)
    body = visible(client.get(reverse("coordinator:review", args=[CODE])))
    rows = {p.code: body.split(f"<code>{p.code}</code>")[1].split("</tr>")[0]
            for p in (world.linear, world.curvilinear, world.full)}  # fmt: skip
    assert (
        '4 / 4 <span class="text-success" aria-label="complete">✓</span>' in rows[world.linear.code]
    )
    assert (
        '2 / 2 <span class="text-success" aria-label="complete">✓</span>'
        in rows[world.curvilinear.code]
    )
    assert "0 / 8" in rows[world.full.code] and "complete" not in rows[world.full.code]


def test_invitation_page_sets_the_scope(client, world):
    lab = LaboratoryFactory.create(name="Lab new")
    client.force_login(world.coordinator)
    response = client.post(
        reverse("coordinator:invite", args=[CODE]),
        {"laboratories": [lab.pk], "devices": [world.mems1.pk], "benches": ["linear"],
         "frequencies_hz": "10"},
    )  # fmt: skip
    assert response.status_code == 302
    participant = Participant.objects.get(laboratory=lab)
    assert labels(participant) == [("MEMS 1", "linear", 10)]


def test_scope_forms_offer_the_rounds_own_benches_and_devices_by_name(client, world):
    """The round has the linear and curvilinear benches and axis X only: the invitation and
    scope pages offer those (not sine-on-random, not Y or Z), devices by their name."""
    import re

    LaboratoryFactory.create(name="Lab new")
    client.force_login(world.coordinator)
    for url in (
        reverse("coordinator:invite", args=[CODE]),
        reverse("coordinator:scope", args=[CODE, world.linear.code]),
    ):
        page = client.get(url).content.decode()
        benches = re.findall(r'name="benches" value="([^"]+)"', page)
        axes = re.findall(r'name="axes" value="([^"]+)"', page)
        assert (sorted(benches), axes) == (["curvilinear", "linear"], ["X"]), url
        assert "MEMS 1</label>" in page and "MEMS 1 (" not in page, url


def test_invitation_api_takes_an_optional_scope(world):
    client = APIClient()
    client.force_authenticate(world.coordinator)
    labs = [LaboratoryFactory.create(name=n) for n in ("Lab old style", "Lab scoped")]
    old = client.post(f"{API}/participants/", {"laboratories": ["Lab old style"]}, format="json")
    assert old.status_code == 201
    assert old.json()["participants"][0]["scope"]["description"] == "every measurement point"
    new = client.post(
        f"{API}/participants/",
        {"laboratories": ["Lab scoped"], "scope": {"devices": ["mems 1"], "axes": ["x"]}},
        format="json",
    )
    assert new.status_code == 201
    scope = new.json()["participants"][0]["scope"]
    assert (scope["devices"], scope["axes"], scope["n_measurement_points"]) == (
        ["MEMS 1"],
        ["X"],
        4,
    )
    assert participant_points(Participant.objects.get(laboratory=labs[0])).count() == 8
    bad = client.post(
        f"{API}/participants/",
        {"laboratories": [LaboratoryFactory.create(name="Lab bad").name],
         "scope": {"devices": ["MEMS 7"]}},
        format="json",
    )  # fmt: skip
    assert bad.status_code == 400
    assert bad.json()["errors"][0]["message"] == f"MEMS 7 is not a device of {CODE}"
    assert not Participant.objects.filter(laboratory__name="Lab bad").exists()  # atomic


def test_coordinator_changes_the_scope_on_the_web_until_the_deadline(client, world):
    client.force_login(world.coordinator)
    url = reverse("coordinator:scope", args=[CODE, world.full.code])
    assert "Every measurement point" in visible(client.get(url))
    response = client.post(url, {"benches": ["curvilinear"], "axes": ["X"]})
    assert response.status_code == 302
    assert scope_text(Participant.objects.get(pk=world.full.pk)) == "bench curvilinear; axis X"
    world.comparison.submission_deadline = timezone.now() - dt.timedelta(minutes=1)
    world.comparison.save()
    response = client.post(url, {"benches": ["linear"]})
    assert response.status_code == 200
    assert "scopes can no longer be changed" in visible(response)
    assert Participant.objects.get(pk=world.full.pk).scope_benches == ["curvilinear"]


def test_coordinator_changes_the_scope_by_api_until_the_deadline(world):
    client = APIClient()
    client.force_authenticate(world.coordinator)
    url = f"{API}/participants/{world.linear.code}/scope/"
    got = client.get(url)
    assert got.status_code == 200
    assert got.json() == {
        "participant": world.linear.code, "devices": [], "benches": ["linear"], "axes": [],
        "frequencies_hz": [], "description": "bench linear", "n_measurement_points": 4,
    }  # fmt: skip
    put = client.put(url, {"benches": ["linear"], "frequencies_hz": [10.0]}, format="json")
    assert put.status_code == 200
    assert (put.json()["frequencies_hz"], put.json()["n_measurement_points"]) == ([10.0], 2)
    world.comparison.submission_deadline = timezone.now() - dt.timedelta(minutes=1)
    world.comparison.save()
    late = client.put(url, {}, format="json")
    assert late.status_code == 409
    assert "scopes can no longer be changed" in late.json()["detail"]
    assert Participant.objects.get(pk=world.linear.pk).scope_frequencies_hz == [10.0]


def test_another_coordinator_cannot_see_or_change_a_scope(client, world):
    other = UserFactory.create(username="coord-other")
    ComparisonFactory.create(code="IMU-OTHER").coordinators.add(other)
    api = APIClient()
    api.force_authenticate(other)
    url = f"{API}/participants/{world.linear.code}/scope/"
    assert api.get(url).status_code == 404
    assert api.put(url, {}, format="json").status_code == 404
    client.force_login(other)
    page = reverse("coordinator:scope", args=[CODE, world.linear.code])
    assert client.get(page).status_code == 404
    assert client.post(page, {}).status_code == 404
    assert Participant.objects.get(pk=world.linear.pk).scope_benches == ["linear"]


def test_a_participant_cannot_change_its_scope(world):
    client = world.api(world.linear)
    response = client.put(f"{API}/participants/{world.linear.code}/scope/", {}, format="json")
    assert response.status_code == 403
    assert Participant.objects.get(pk=world.linear.pk).scope_benches == ["linear"]


# --- the coordinator's import_results ---------------------------------------------------------


def import_table(world, recs):
    import io

    from labs.bulk_import import results_import
    from labs.importers import write_table

    return results_import(
        comparison=world.comparison, file=io.BytesIO(write_table(recs)), user=world.coordinator
    )


def with_lab(participant, recs):
    return [{"lab": participant.code, **r} for r in recs]


def test_import_results_needs_each_scope_only(world):
    recs = with_lab(world.linear, records(participant_points(world.linear)))
    recs += with_lab(world.curvilinear, records(participant_points(world.curvilinear)))
    summary = import_table(world, recs)
    assert (summary.participants, summary.rows, summary.new_versions) == (2, 6, 2)
    assert Submission.objects.get(participant=world.linear).results.count() == 4
    assert Submission.objects.get(participant=world.curvilinear).results.count() == 2


def test_import_results_refuses_a_row_outside_a_scope_and_lists_missing_scope_points(world):
    from labs.bulk_import import ImportRefused

    outside = world.comparison.measurement_points.get(
        device=world.mems1, bench="linear", frequency_hz=5
    )
    recs = with_lab(world.curvilinear, records(participant_points(world.curvilinear))[:1])
    with pytest.raises(ImportRefused) as err:
        import_table(world, recs + with_lab(world.curvilinear, records([outside])))
    assert [str(e) for e in err.value.row_errors] == [
        f"row 3: MEMS 1, X, 5 Hz, linear vertical is not in the scope of {world.curvilinear.code} "
        "(device MEMS 2; bench curvilinear)"
    ]
    with pytest.raises(ImportRefused) as err:
        import_table(world, recs)
    assert [str(e) for e in err.value.row_errors] == [
        f"column lab: {world.curvilinear.code}: missing result for MEMS 2, X, 10 Hz, curvilinear "
        "tangential; a submission needs a result for every measurement point of its scope"
    ]
    assert not Submission.objects.filter(participant__comparison=world.comparison).exists()


# --- more of the pages and the API's refusals -------------------------------------------------


def test_xlsx_upload_outside_the_scope_is_a_row_error(client, world):
    import io

    import openpyxl

    workbook = openpyxl.Workbook()
    sheet = workbook.active
    sheet.append(HEADER.strip().split(","))
    for r in records(participant_points(world.curvilinear)):
        sheet.append(list(r.values()))
    sheet.append(["MEMS 1", "X", 10, "curvilinear", "tangential", 420.5, 8.4])
    buffer = io.BytesIO()
    workbook.save(buffer)
    client.force_login(world.staff(world.curvilinear))
    response = client.post(
        reverse("labs:upload", args=[CODE]),
        {"file": SimpleUploadedFile("r.xlsx", buffer.getvalue()), "action": "submit"},
    )
    assert response.status_code == 200
    assert (
        '<td data-label="Row" class="text-nowrap">row 4</td>\n'
        '        <td data-label="Column">—</td>\n'
        '        <td data-label="Problem">MEMS 1, X, 10 Hz, curvilinear tangential is not in your '
        "scope (device MEMS 2; bench curvilinear)</td>"
    ) in visible(response)
    assert not Submission.objects.filter(participant=world.curvilinear).exists()


def test_coordinator_pages_show_the_scopes(client, world):
    client.force_login(world.coordinator)
    body = visible(client.get(reverse("coordinator:comparison", args=[CODE])))
    scope_url = reverse("coordinator:scope", args=[CODE, world.curvilinear.code])
    assert f'<a href="{scope_url}">Device MEMS 2; bench curvilinear<span' in body
    review = visible(client.get(reverse("coordinator:review", args=[CODE])))
    assert '0 / 4 <span class="small text-body-secondary">(scope: bench linear)</span>' in review
    LaboratoryFactory.create(name="Lab not yet invited")  # one checkbox to offer
    invite = visible(client.get(reverse("coordinator:invite", args=[CODE])))
    for name in ("laboratories", "devices", "benches", "axes", "frequencies_hz"):
        assert f'name="{name}"' in invite


def test_scope_api_refuses_bad_values_and_changes_nothing(world):
    client = APIClient()
    client.force_authenticate(world.coordinator)
    url = f"{API}/participants/{world.linear.code}/scope/"
    response = client.put(url, {"benches": ["linear"], "frequencies_hz": [7.5]}, format="json")
    assert response.status_code == 400
    assert response.json()["errors"] == [
        {"row": None, "field": "frequencies_hz", "message": f"7.5 Hz is not a frequency of {CODE}"}
    ]
    assert client.get(f"{API}/participants/L000/scope/").status_code == 404
    stored = Participant.objects.get(pk=world.linear.pk)
    assert (stored.scope_benches, stored.scope_frequencies_hz) == (["linear"], [])


def test_measurands_say_which_points_are_in_the_callers_scope(world):
    response = world.api(world.curvilinear).get(f"{API}/measurands/")
    assert response.status_code == 200
    flags = [(m["device"], m["bench"], m["frequency_hz"], m["in_scope"])
             for m in response.json()["results"]]  # fmt: skip
    assert [f for f in flags if f[3]] == [
        ("MEMS 2", "curvilinear", 5.0, True),
        ("MEMS 2", "curvilinear", 10.0, True),
    ]
    assert len(flags) == 8
    full = world.api(world.full).get(f"{API}/measurands/").json()["results"]
    assert [m["in_scope"] for m in full] == [True] * 8
    coordinator = APIClient()
    coordinator.force_authenticate(world.coordinator)
    answer = coordinator.get(f"{API}/measurands/").json()["results"]
    assert [m["in_scope"] for m in answer] == [None] * 8
