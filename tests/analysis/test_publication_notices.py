"""Publication tells every participant (docs/lifecycles.md §6): one notice and one e-mail
each, with the links to its own results (only it may open them) and to the reports."""

from io import StringIO
from urllib.parse import urlsplit

import pytest
from django.contrib.auth import get_user_model
from django.core import mail
from django.core.management import call_command

from analysis.publication import comparison_publish
from analysis.services import analysis_run_start
from labs.models import Notice, Participant
from proficiency.models import Comparison

CODE = "IMU-2024-DEMO"
SITE = "https://pt.example.org"

pytestmark = pytest.mark.django_db


@pytest.fixture
def analysed(db, django_capture_on_commit_callbacks):
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    demo = Comparison.objects.get(code=CODE)
    with django_capture_on_commit_callbacks(execute=True):
        run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    demo.refresh_from_db()
    demo.authorised_by_name, demo.authorised_by_role = "A. Quality", "Quality manager"
    demo.save()
    return demo


def test_publication_notice_per_participant(
    client, analysed, settings, django_capture_on_commit_callbacks
):
    settings.SITE_URL = SITE
    mail.outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        comparison_publish(comparison=analysed)
    participants = Participant.objects.filter(comparison=analysed).select_related("laboratory")
    notices = Notice.objects.filter(comparison=analysed, kind="published")
    assert notices.count() == participants.count() == 12
    assert len(mail.outbox) == 12
    alpine = participants.get(laboratory__name="Alpine Vibration Metrology")
    notice = notices.get(participant=alpine)
    assert notice.laboratory == alpine.laboratory and notice.emailed_at is not None
    message = next(m for m in mail.outbox if m.to == list(notice.emailed_to.split(", ")))
    assert message.subject == "[IMU-2024-DEMO] results published"
    # the old e-mail's text is kept, now with the links
    assert "are published. Sign in to see your scores and download your report." in message.body
    assert f"Reports: {SITE}/reports/{CODE}/" in message.body
    link = f"{SITE}/results/{CODE}/"
    assert f"Open: {link}" in message.body
    path = urlsplit(link).path
    users = get_user_model().objects
    # Alpine (lab03) has a staff member and a manager: one e-mail to both
    assert sorted(message.to) == ["lab03-manager@example.org", "lab03@example.org"]
    addressee = users.get(username="lab03")
    client.force_login(addressee)
    assert client.get(path).status_code == 200
    assert client.get(f"/reports/{CODE}/").status_code == 200
    outsider = users.create_user("outsider", "outsider@example.org", "pw-outsider-1")
    client.force_login(outsider)
    assert client.get(path).status_code == 404
    # publishing is final: no second notice can be made by the service
    from analysis.publication import notify_published

    assert notify_published(analysed) == 0 and Notice.objects.count() == 12
