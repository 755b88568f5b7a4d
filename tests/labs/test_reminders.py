"""Deadline reminders by Celery beat (docs/lifecycles.md §6): N days before the deadline,
to every participant that has not submitted, once per participant and N."""

import datetime as dt

import pytest
from django.conf import settings
from django.core import mail
from django.core.exceptions import ValidationError
from django.utils import timezone

from labs.models import Notice
from labs.notices import reminders_send
from labs.tasks import notices_reminders_task
from proficiency.models import Comparison, reminder_days_parse, validate_reminder_days
from tests.factories import (
    ComparisonFactory,
    LaboratoryFactory,
    MembershipFactory,
    ParticipantFactory,
    SubmissionFactory,
    UserFactory,
)

pytestmark = pytest.mark.django_db


@pytest.fixture
def round_(db):
    deadline = timezone.now() + dt.timedelta(days=6, hours=12)  # the 7-day reminder is due
    comparison = ComparisonFactory.create(
        code="IMU-R1", status="open", submission_deadline=deadline
    )
    parts = {}
    for name, code in (("Waiting Lab", "L01"), ("Draft Lab", "L02"), ("Done Lab", "L03")):
        lab = LaboratoryFactory.create(name=name)
        MembershipFactory.create(laboratory=lab, user=UserFactory.create(username=code.lower()))
        parts[name] = ParticipantFactory.create(comparison=comparison, laboratory=lab, code=code)
    SubmissionFactory.create(participant=parts["Draft Lab"], status="draft")
    SubmissionFactory.create(
        participant=parts["Done Lab"], status="submitted", submitted_at=timezone.now()
    )
    return comparison


def test_the_beat_entry_names_the_task():
    entry = settings.CELERY_BEAT_SCHEDULE["notices-reminders"]
    assert entry["task"] == notices_reminders_task.name == "labs.tasks.notices_reminders_task"


def test_reminder_task_run_twice_sends_once(round_, django_capture_on_commit_callbacks):
    with django_capture_on_commit_callbacks(execute=True):
        first = notices_reminders_task.delay().get()
    assert first == {"reminders": 2, "resent": 0}
    reminders = Notice.objects.filter(kind="reminder").order_by("participant__code")
    # a draft is no submission: L02 is reminded too
    assert [n.participant and n.participant.code for n in reminders] == ["L01", "L02"]
    assert sorted(m.to[0] for m in mail.outbox) == ["l01@example.org", "l02@example.org"]
    notice = reminders[0]
    assert notice.subject == "[IMU-R1] reminder: the deadline is in 7 days"
    assert "We have no submitted results from Waiting Lab (participant L01) yet." in notice.body
    assert notice.link == "/lab/comparisons/IMU-R1/"
    with django_capture_on_commit_callbacks(execute=True):
        second = notices_reminders_task.delay().get()
    assert second == {"reminders": 0, "resent": 0}
    assert Notice.objects.count() == 2 and len(mail.outbox) == 2


def test_the_one_day_reminder_comes_later_and_once(round_, django_capture_on_commit_callbacks):
    deadline = round_.submission_deadline
    with django_capture_on_commit_callbacks(execute=True):
        assert reminders_send(now=deadline - dt.timedelta(days=6)) == 2  # 7 days
        assert reminders_send(now=deadline - dt.timedelta(days=3)) == 0  # nothing due
        assert reminders_send(now=deadline - dt.timedelta(hours=20)) == 2  # 1 day
        assert reminders_send(now=deadline - dt.timedelta(hours=2)) == 0
        assert reminders_send(now=deadline + dt.timedelta(hours=1)) == 0  # past the deadline
    subjects = sorted(Notice.objects.values_list("subject", flat=True))
    assert (
        subjects
        == ["[IMU-R1] reminder: the deadline is in 1 day"] * 2
        + ["[IMU-R1] reminder: the deadline is in 7 days"] * 2
    )
    assert len(mail.outbox) == 4


def test_only_the_nearest_due_reminder_is_sent(round_):
    deadline = round_.submission_deadline
    assert reminders_send(now=deadline - dt.timedelta(hours=5)) == 2  # 7 and 1 both passed
    assert set(Notice.objects.values_list("subject", flat=True)) == {
        "[IMU-R1] reminder: the deadline is in 1 day"
    }


def test_reminder_days_per_round(round_):
    round_.reminder_days = "3"
    round_.save()
    assert reminders_send(now=round_.submission_deadline - dt.timedelta(days=6)) == 0
    assert reminders_send(now=round_.submission_deadline - dt.timedelta(days=2)) == 2
    round_.reminder_days = ""
    round_.save()
    Notice.objects.all().delete()
    assert reminders_send(now=round_.submission_deadline - dt.timedelta(hours=1)) == 0


def test_closed_rounds_and_rounds_without_deadline_are_not_reminded(round_):
    Comparison.objects.filter(pk=round_.pk).update(status="closed")
    ComparisonFactory.create(status="open", submission_deadline=None)
    assert reminders_send() == 0 and Notice.objects.count() == 0


def test_a_new_comparison_reminds_seven_and_one_day_before():
    assert ComparisonFactory.create().reminder_days == "7,1"
    assert reminder_days_parse("7, 1,,7") == [1, 7]


@pytest.mark.parametrize("bad", ["7;1", "0", "x", "-1", "400", "²", "7,¹"])
def test_bad_reminder_days_say_what_is_wrong(bad):
    with pytest.raises(ValidationError) as err:
        validate_reminder_days(bad)
    assert "is not a number of days from 1 to 365" in str(err.value)
