"""The world the security tests probe: two laboratories, two comparisons, nine personas.

Lab A's secrets (its name, its participant code in comparison 1, a distinctive
sensitivity) are chosen so that they cannot appear in a page by accident; any
response to someone who must not see them is checked for them.

* comparison 1 (``SEC-C1``, analysed, not published): labs A, B and C take part,
  coordinated by ``coord1``; one successful analysis run; a preliminary summary and a
  preliminary participant report for lab A; the coordinators' archive of the run (a ZIP
  of its outputs and those two reports, built inline: a small run); lab A has an accepted
  version 1 and a draft version 2, labs B and C only a version 1 (so version 2 is lab A's
  alone);
* comparison 2 (``SEC-C2``, open): lab B takes part, coordinated by ``coord2``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from django.contrib.auth.models import Permission
from django.test import Client

from analysis.archive import archive_request
from analysis.models import AnalysisRun, Report
from analysis.reports.services import report_issue
from analysis.services import analysis_run_start
from labs.models import LabAPIKey, Laboratory, Membership, Participant, Result, Submission
from labs.services import api_key_create, api_key_revoke
from proficiency.models import (
    AssignedValueMethod,
    Comparison,
    ComparisonStatus,
    MeasurementPoint,
)
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MeasurementPointFactory,
    UserFactory,
)

LAB_A_NAME = "Zephyrine Vibration Secrets"
LAB_A_CODE = "QZ7X"
LAB_A_VALUE = 123.456789
#: what lab A's value looks like however a page formats it
LAB_A_VALUE_TEXTS = ("123.456789", "123.45679", "123.4568")
C1, C2 = "SEC-C1", "SEC-C2"
PASSWORD = "correct horse battery staple"

PERSONAS = (
    "anonymous", "a_staff", "a_manager", "b_staff", "coord1", "coord2", "key_a",
    "key_a_revoked", "superuser",
)  # fmt: skip
#: personas that must never see lab A's name, code or values
OUTSIDERS = ("anonymous", "b_staff", "coord2", "key_a_revoked")


@dataclass
class World:
    c1: Comparison
    c2: Comparison
    lab_a: Laboratory
    lab_b: Laboratory
    point: MeasurementPoint
    run: AnalysisRun
    result_a: Result
    report_a: Report
    report_summary: Report
    key_a: LabAPIKey
    key_a_secret: str
    key_a_revoked: LabAPIKey
    key_a_revoked_secret: str
    users: dict[str, Any] = field(default_factory=dict)

    def url_values(self) -> dict[str, Any]:
        """Values for the URL kwargs: always lab A's objects in comparison 1."""
        return {
            "code": C1,
            "version": 2,
            "participant": LAB_A_CODE,
            "lab": LAB_A_CODE,
            "lab_pk": self.lab_a.pk,
            "prefix": self.key_a.prefix,
            "token": self.report_a.token,
            "fmt": "csv",
            "run": self.run.pk,
            "point": self.point.pk,
            "result": self.result_a.pk,
            "uidb64": "MQ",
            "reset_token": "set-password",
            "action": "publish",
            "which": "summary",
            "chart": "z",
            "ext": "png",
        }

    def client(self, persona: str) -> Client:
        client = Client(raise_request_exception=False)
        if persona in self.users:
            client.force_login(self.users[persona])
        elif persona == "key_a":
            client.defaults["HTTP_AUTHORIZATION"] = f"Api-Key {self.key_a_secret}"
        elif persona == "key_a_revoked":
            client.defaults["HTTP_AUTHORIZATION"] = f"Api-Key {self.key_a_revoked_secret}"
        return client


def _lab(name: str, *members: tuple[str, str]) -> tuple[Laboratory, dict[str, Any]]:
    lab = LaboratoryFactory.create(name=name)
    users = {}
    for username, role in members:
        users[username] = UserFactory.create(username=username)
        Membership.objects.create(user=users[username], laboratory=lab, role=role)
    return lab, users


def _submission(participant: Participant, version: int, status: str, value: float,
                points: list[MeasurementPoint]) -> list[Result]:  # fmt: skip
    submission = Submission.objects.create(participant=participant, version=version, status=status)
    return [
        Result.objects.create(
            submission=submission,
            measurement_point=p,
            value=value + i * 0.5,
            unit="mV/(m/s^2)",
            expanded_uncertainty=0.8,
            coverage_factor=2.0,
        )
        for i, p in enumerate(points)
    ]


def _coordinator(username: str, comparison: Comparison) -> Any:
    user = UserFactory.create(username=username)
    user.user_permissions.add(Permission.objects.get(codename="add_comparison"))
    comparison.coordinators.add(user)
    return user


def build_world(capture_on_commit: Any) -> World:
    """Create everything; ``capture_on_commit`` is pytest-django's
    ``django_capture_on_commit_callbacks`` (the analysis task is enqueued on commit)."""
    lab_a, users = _lab(LAB_A_NAME, ("a_staff", "staff"), ("a_manager", "manager"))
    lab_b, users_b = _lab("Bravo Calibration", ("b_staff", "staff"))
    lab_c, _ = _lab("Charlie Metrology")
    c1 = ComparisonFactory.create(
        code=C1, status=ComparisonStatus.CLOSED,
        assigned_value_method=AssignedValueMethod.WEIGHTED_MEAN,
    )  # fmt: skip
    c2 = ComparisonFactory.create(code=C2, status=ComparisonStatus.OPEN)
    users |= users_b
    users["coord1"] = _coordinator("coord1", c1)
    users["coord2"] = _coordinator("coord2", c2)
    users["superuser"] = UserFactory.create(username="root", is_superuser=True, is_staff=True)
    device = DeviceFactory.create(comparison=c1, nominal_sensitivity=123.0, unit="mV/(m/s^2)")
    points = [MeasurementPointFactory.create(device=device, frequency_hz=f) for f in (10.0, 80.0)]
    MeasurementPointFactory.create(device=DeviceFactory.create(comparison=c2), frequency_hz=10.0)
    part_a = Participant.objects.create(comparison=c1, laboratory=lab_a, code=LAB_A_CODE)
    part_b = Participant.objects.create(comparison=c1, laboratory=lab_b, code="KB2")
    part_c = Participant.objects.create(comparison=c1, laboratory=lab_c, code="KC3")
    Participant.objects.create(comparison=c2, laboratory=lab_b, code="KB9")
    accepted = Submission.Status.ACCEPTED
    result_a = _submission(part_a, 1, accepted, LAB_A_VALUE, points)[0]
    _submission(part_a, 2, Submission.Status.DRAFT, LAB_A_VALUE, points)
    _submission(part_b, 1, accepted, 122.9, points)
    _submission(part_c, 1, accepted, 123.2, points)
    with capture_on_commit(execute=True):
        run = analysis_run_start(comparison=c1, user=users["coord1"])
    run.refresh_from_db()
    assert run.status == AnalysisRun.Status.SUCCEEDED, run.error
    c1.refresh_from_db()
    summary = report_issue(comparison=c1, kind=Report.Kind.SUMMARY)
    report_a = report_issue(comparison=c1, kind=Report.Kind.PARTICIPANT, participant=part_a)
    assert archive_request(comparison=c1, run=run).status == "ready"
    key_a, secret = api_key_create(laboratory=lab_a, name="acquisition PC", user=None)
    revoked, revoked_secret = api_key_create(laboratory=lab_a, name="old PC", user=None)
    api_key_revoke(key=revoked)
    return World(
        c1=c1, c2=c2, lab_a=lab_a, lab_b=lab_b, point=points[0], run=run, result_a=result_a,
        report_a=report_a, report_summary=summary, key_a=key_a, key_a_secret=secret,
        key_a_revoked=revoked, key_a_revoked_secret=revoked_secret, users=users,
    )  # fmt: skip
