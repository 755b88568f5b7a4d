"""A two-bench round end to end in real Chromium, as the people who run it would.

One MEMS on the linear_and_curvilinear protocol: 9 linear points and 18 curvilinear ones.
Two laboratories that each run one bench enrol through the open call with their own scope
(linear only, curvilinear only); the coordinator accepts both, opens the round; Celery beat's
reminder task runs twice (one reminder each); each laboratory fills the grid for its own
scope only and submits complete (a receipt each); the coordinator closes, accepts both
complete submissions in one action, runs the analysis, previews the reports, confirms and
publishes in the background; each laboratory opens the link of its publication e-mail and
finds its scores and its report, and the same link answers 404 to a laboratory outside the
round. No number on the pages shows floating-point noise.
"""

from __future__ import annotations

import datetime as dt
import re
from urllib.parse import urlsplit

import pytest
from django.core import mail
from django.utils import timezone
from playwright.sync_api import Page, expect

from labs.models import Enrolment, Membership, Notice, Participant, Submission
from labs.tasks import notices_reminders_task
from proficiency.models import Comparison, ComparisonStatus
from proficiency.services import comparison_apply_template
from tests.factories import ComparisonFactory, DeviceFactory, LaboratoryFactory, UserFactory

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

PASSWORD = "correct horse battery staple"  # tests.factories.UserFactory's
CODE = "IMU-TWO-BENCH"
#: a float as the machine stores it: what no page may show
NOISE = re.compile(r"\d\.\d{7,}")
LABS = {  # username -> (laboratory, bench measured, number of its points)
    "lin-mgr": ("Alpha Linear Laboratory", "linear", 9),
    "cur-mgr": ("Bravo Curvilinear Laboratory", "curvilinear", 18),
}


@pytest.fixture
def call(db) -> Comparison:
    comparison = ComparisonFactory.create(
        code=CODE, title="Two benches, one MEMS", status=ComparisonStatus.DRAFT,
        protocol="linear_and_curvilinear", enrolment_open=True,
        # the 7-day reminder is due from the start, the 1-day one is not
        submission_deadline=timezone.now() + dt.timedelta(days=5),
        assigned_value_method="nominal", sigma_pt_mode="relative", sigma_pt_value=1.0,
        authorised_by_name="Dana Quality", authorised_by_role="Quality manager",
    )  # fmt: skip
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1")
    comparison_apply_template(
        comparison=comparison, template_key="linear_and_curvilinear", devices=[device]
    )
    comparison.coordinators.add(UserFactory.create(username="carla"))
    for username, (name, _bench, _n) in LABS.items():
        lab = LaboratoryFactory.create(name=name)
        user = UserFactory.create(username=username)
        Membership.objects.create(user=user, laboratory=lab, role=Membership.Role.MANAGER)
    outsider = LaboratoryFactory.create(name="Nosy Neighbour Laboratory")
    Membership.objects.create(
        user=UserFactory.create(username="nosy"), laboratory=outsider,
        role=Membership.Role.MANAGER,
    )  # fmt: skip
    return comparison


def _sign_in(page: Page, base: str, username: str) -> None:
    page.goto(f"{base}/accounts/login/")
    page.get_by_label("Username").fill(username)
    page.get_by_label("Password").fill(PASSWORD)
    page.get_by_role("button", name="Sign in").click()
    expect(page.get_by_role("button", name="Log out")).to_be_visible()


def _no_noise(page: Page) -> None:
    text = page.locator("main").inner_text()
    assert not NOISE.findall(text), f"{page.url}: {NOISE.findall(text)[:5]}"


def _link_of(username: str, kind: str) -> str:
    """The path of the link in the last e-mail of ``kind``'s subject sent to ``username``."""
    notice = Notice.objects.filter(kind=kind, participant__laboratory__name=LABS[username][0])
    subject = notice.get().subject
    (message,) = [
        m for m in mail.outbox if m.subject == subject and m.to == [f"{username}@example.org"]
    ]
    (line,) = [x for x in message.body.splitlines() if x.startswith("Open: ")]
    return urlsplit(line.removeprefix("Open: ")).path


def test_two_bench_round_from_call_to_published_reports(
    page: Page, new_context, live_server, shots, console_errors, call
):
    base = live_server.url
    pages: dict[str, Page] = {}
    for username in ("carla", *LABS, "nosy"):
        pages[username] = page if username == "carla" else new_context().new_page()
        if username in LABS:  # carla's page is watched by the fixture; nosy's meets a 404
            console_errors.watch(pages[username])
        _sign_in(pages[username], base, username)

    # 1. each laboratory applies to the open call with its own bench
    for username, (_name, bench, _n) in LABS.items():
        lab = pages[username]
        lab.get_by_role("link", name="Open calls").first.click()
        row = lab.locator("tr", has_text=CODE)
        row.get_by_role("link", name=re.compile("Apply")).click()
        expect(lab.get_by_role("heading", name=f"Apply to {CODE}")).to_be_visible()
        lab.get_by_label(bench.capitalize(), exact=True).check()
        lab.get_by_label("Note to the coordinator").fill(f"We run the {bench} bench only.")
        shots(lab, f"apply-{bench}")
        lab.get_by_role("button", name="Send the application").click()
        expect(lab.locator("tr", has_text=CODE).first).to_contain_text("Applied")
    assert Enrolment.objects.filter(comparison=call, status="pending").count() == 2

    # 2. the coordinator accepts both as asked, and opens the round
    carla = pages["carla"]
    carla.goto(f"{base}/coordinator/{CODE}/")
    expect(carla.locator("#applications")).to_contain_text("2 pending")
    carla.get_by_role("link", name=re.compile("All applications")).click()
    shots(carla, "applications")
    for name, _bench, _n in LABS.values():
        carla.get_by_role("link", name=f"Accept… {name}").click()
        carla.get_by_role("button", name="Accept and invite").click()
        expect(carla.locator("tr", has_text=name)).to_contain_text("Accepted")
    scopes = {
        p.laboratory.name: p.scope_benches for p in Participant.objects.filter(comparison=call)
    }
    assert scopes == {name: [bench] for name, bench, _n in LABS.values()}
    carla.goto(f"{base}/coordinator/{CODE}/")
    carla.get_by_role("link", name="Open for submissions…").click()
    expect(carla.locator("main")).to_contain_text("2 participating laboratories are e-mailed")
    shots(carla, "confirm-open")
    carla.get_by_role("button", name="Open for submissions").click()
    call.refresh_from_db()
    assert call.status == ComparisonStatus.OPEN

    # 3. Celery beat's reminder task, twice: one reminder each
    notices_reminders_task()
    notices_reminders_task()
    assert Notice.objects.filter(comparison=call, kind=Notice.Kind.REMINDER).count() == 2

    # 4. each laboratory fills the grid of its own scope and submits it complete
    for username, (name, bench, n_points) in LABS.items():
        lab = pages[username]
        lab.goto(f"{base}/lab/")
        expect(lab.get_by_text(re.compile("reminder", re.I)).first).to_be_visible()
        lab.goto(f"{base}/lab/comparisons/{CODE}/results/")
        values = lab.locator("input[name$='-sensitivity']")
        expect(values).to_have_count(n_points)
        for i in range(n_points):
            values.nth(i).fill(f"{418.1 + 0.01 * i:.2f}")
        uncertainties = lab.locator("input[name$='-expanded_uncertainty']")
        for i in range(n_points):
            uncertainties.nth(i).fill("4.2")
        shots(lab, f"grid-{bench}")
        lab.get_by_role("button", name="Submit results").click()
        expect(lab.get_by_text(re.compile("submitted", re.I)).first).to_be_visible()
        submission = Submission.objects.get(participant__laboratory__name=name)
        assert (submission.status, submission.results.count()) == ("submitted", n_points)
        assert (
            Notice.objects.filter(
                kind=Notice.Kind.RECEIPT, participant=submission.participant
            ).count()
            == 1
        )

    # 5. closed; both complete submissions accepted in one action
    carla.goto(f"{base}/coordinator/{CODE}/")
    carla.get_by_role("link", name="Close submissions…").click()
    carla.get_by_role("button", name="Close submissions").click()
    carla.goto(f"{base}/coordinator/{CODE}/review/")
    shots(carla, "review")
    carla.get_by_role("link", name="Accept 2 complete submissions…").click()
    codes = sorted(Participant.objects.filter(comparison=call).values_list("code", flat=True))
    for code in codes:
        expect(carla.locator("main")).to_contain_text(code)
    shots(carla, "confirm-accept-all")
    carla.get_by_role("button", name="Accept 2 submissions").click()
    expect(carla.get_by_text(re.compile("Accepted 2 submissions"))).to_be_visible()
    assert set(
        Submission.objects.filter(participant__comparison=call).values_list("status", flat=True)
    ) == {"accepted"}
    _no_noise(carla)

    # 6. analysis, preview of the reports, confirmation, publication in the background
    carla.goto(f"{base}/coordinator/{CODE}/")
    carla.get_by_role("link", name="Run analysis…").click()
    carla.get_by_role("button", name="Run analysis").click()
    expect(carla.locator("#run-progress .badge")).to_have_text("Succeeded", timeout=60_000)
    carla.get_by_role("link", name="See the results").click()
    _no_noise(carla)
    carla.get_by_role("link", name="Preview reports").first.click()
    for code in codes:
        expect(carla.locator("main")).to_contain_text(code)
    shots(carla, "reports-preview")
    carla.go_back()
    carla.get_by_role("link", name="Publish results…").click()
    expect(carla.locator("main")).to_contain_text("2 laboratories")
    shots(carla, "confirm-publish")
    carla.get_by_role("button", name="Publish results").click()
    progress = carla.locator("#publication-progress")
    expect(progress).to_have_attribute("data-status", "succeeded", timeout=60_000)
    shots(carla, "published")
    call.refresh_from_db()
    assert call.status == ComparisonStatus.PUBLISHED

    # 7. each laboratory follows its e-mail's link to its scores and its report
    for username, (name, bench, n_points) in LABS.items():
        lab = pages[username]
        own = Participant.objects.get(comparison=call, laboratory__name=name)
        path = _link_of(username, Notice.Kind.PUBLISHED)
        lab.goto(base + path)
        expect(lab.locator("main")).to_contain_text(own.code)
        _no_noise(lab)
        shots(lab, f"published-{bench}")
        lab.goto(f"{base}/results/{CODE}/scores/")
        expect(lab.locator("table tbody tr").filter(has_text=own.code)).to_have_count(n_points)
        _no_noise(lab)
        lab.goto(f"{base}/reports/{CODE}/")
        listed = lab.locator("table tbody tr")
        expect(listed.filter(has_text=f"Participant report {own.code}")).to_have_count(1)
        with lab.expect_download() as info:
            listed.filter(has_text=f"Participant report {own.code}").get_by_role("link").click()
        assert open(info.value.path(), "rb").read(5) == b"%PDF-"  # noqa: SIM115
        # the link is the addressee's: a laboratory outside the round gets 404
        response = pages["nosy"].goto(base + path)
        assert response is not None and response.status == 404
    assert console_errors == []
