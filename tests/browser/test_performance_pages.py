"""How a laboratory did, in the browser, on the demo round analysed and published: the
participant reads its summary first on its results page; the round's coordinator reads
every participant's counts, then one participant's summary; the coordinator of another
round and a laboratory of another round get 404. Screenshots in
test-artifacts/browser/<test>/ (looked at when the pages change)."""

from __future__ import annotations

import pytest
from django.contrib.auth import get_user_model
from playwright.sync_api import Page, expect

from analysis.performance import lab_performance
from analysis.selectors import current_run
from analysis.services import analysis_run_start
from coordination.demo import load_demo
from labs.models import Participant
from proficiency.models import Comparison
from tests.browser.test_two_bench_round import PASSWORD, _sign_in

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

CODE = "IMU-2024-DEMO"


def test_participant_and_coordinators_read_the_performance_summary(
    page: Page, new_context, live_server, shots, console_errors
):
    load_demo(password=PASSWORD)
    demo = Comparison.objects.get(code=CODE)
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    Comparison.objects.filter(pk=demo.pk).update(status="published")
    assert current_run(demo) == run
    base = live_server.url
    lab = Participant.objects.get(comparison=demo, laboratory__members__user__username="lab05")
    summary = lab_performance(run, lab.code)
    assert summary is not None

    _sign_in(page, base, "lab05")
    page.goto(f"{base}/results/{CODE}/")
    card = page.locator("#performance")
    expect(card.get_by_role("heading", name=f"How {lab.code} did")).to_be_visible()
    t = summary.total
    expect(card).to_contain_text(f"{t.en.satisfactory} of {t.en.scored} results satisfactory")
    expect(card.locator("table.performance-device tbody tr")).to_have_count(3)
    expect(card.locator("table.worst-en tbody tr")).to_have_count(5)
    shots(page, "participant-results-summary")
    # at 1280 px no table of the page scrolls sideways (units under the headings)
    for scroll, width in page.locator(".table-responsive").evaluate_all(
        "els => els.map(e => [e.scrollWidth, e.clientWidth])"
    ):
        assert scroll <= width, f"a table of the results page scrolls sideways ({scroll} > {width})"
    page.get_by_role("link", name=f"All scores of {lab.code}, largest |En| first").click()
    expect(page.locator("tbody tr.own-row").first).to_be_visible()
    shots(page, "participant-scores-largest-first")
    assert page.goto(f"{base}/coordinator/{CODE}/performance/").status == 404  # type: ignore[union-attr]

    coordinator = new_context().new_page()
    console_errors.watch(coordinator)
    _sign_in(coordinator, base, "coordinator")
    coordinator.goto(f"{base}/coordinator/{CODE}/results/")
    coordinator.get_by_role("link", name="Performance").click()
    rows = coordinator.locator("#performance-table tbody tr")
    expect(rows).to_have_count(demo.participants.count())
    shots(coordinator, "coordinator-performance-all")
    coordinator.get_by_role("link", name=lab.code, exact=True).click()
    expect(coordinator.get_by_role("heading", name=f"How {lab.code} did")).to_be_visible()
    shots(coordinator, "coordinator-performance-one")

    get_user_model().objects.create_user("other-coordinator", password=PASSWORD)
    other = Comparison.objects.create(code="OTHER-ROUND", title="Another round")
    other.coordinators.add(get_user_model().objects.get(username="other-coordinator"))
    stranger = new_context().new_page()
    _sign_in(stranger, base, "other-coordinator")
    for path in ("performance/", f"performance/{lab.code}/"):
        response = stranger.goto(f"{base}/coordinator/{CODE}/{path}")
        assert response is not None and response.status == 404, path
    # the only errors: the 404 answers asked for above
    assert [e for e in console_errors if "status of 404" not in e] == []
