"""A kit's loop in the browser (docs/domain.md §15), as the people who run it: the round's
coordinator creates a kit, plans its loop (a wrong line named) and sends it out; the first
laboratory logs the arrival as damaged and sends it on, seeing only its own slot; the
coordinator reads the mark; another round's coordinator gets 404. Screenshots in
test-artifacts/browser/<test>/."""

from __future__ import annotations

import pytest
from django.contrib.auth import get_user_model
from playwright.sync_api import Page, expect

from coordination.demo import load_demo
from labs.models import Handover, Participant
from proficiency.models import Comparison
from tests.browser.test_two_bench_round import PASSWORD, _sign_in

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

CODE = "IMU-2024-DEMO"


def test_a_kit_goes_out_arrives_damaged_and_the_coordinator_sees_it(
    page: Page, new_context, live_server, shots, console_errors
):
    load_demo(password=PASSWORD)
    demo = Comparison.objects.get(code=CODE)
    first = Participant.objects.get(comparison=demo, laboratory__members__user__username="lab05")
    second = Participant.objects.get(comparison=demo, laboratory__members__user__username="lab06")
    base = live_server.url

    _sign_in(page, base, "coordinator")
    page.goto(f"{base}/coordinator/{CODE}/")
    page.get_by_role("link", name="Kits", exact=True).click()
    expect(page.get_by_role("heading", name="Kit A")).to_be_visible()  # the demo's two kits
    page.get_by_label("Name").fill("Kit C")
    for i, device in enumerate(demo.devices.order_by("name"), start=1):
        page.get_by_label(f"Serial of {device.name}").fill(f"C-{i:03d}")
    page.get_by_role("button", name="Create kit").click()
    kit = demo.kits.get(name="Kit C")
    section = page.locator(f"#kit-{kit.pk}")
    section.get_by_label("Circulation plan").fill(
        f"{first.code}, 2027-01-11, 2027-01-22\nL00, x, y"
    )
    section.get_by_role("button", name="Save plan").click()
    expect(page.locator(f"#kit-{kit.pk} .alert-danger")).to_contain_text("line 2: no participant")
    shots(page, "plan-with-a-wrong-line")
    plan = f"{first.code}, 2027-01-11, 2027-01-22\n{second.code}, 2027-01-25, 2027-02-05"
    page.locator(f"#kit-{kit.pk}").get_by_label("Circulation plan").fill(plan)
    page.locator(f"#kit-{kit.pk}").get_by_role("button", name="Save plan").click()
    page.locator(f"#kit-{kit.pk}").get_by_label("Carrier and tracking number").fill("DHL 42")
    page.locator(f"#kit-{kit.pk}").get_by_role("button", name="Send to the first holder").click()
    expect(page.locator(f"#kit-{kit.pk} tbody tr").first).to_contain_text("in transit")

    lab = new_context().new_page()
    console_errors.watch(lab)
    _sign_in(lab, base, "lab05")
    lab.goto(f"{base}/lab/comparisons/{CODE}/")
    lab.get_by_role("link", name="Kit", exact=True).click()
    slot = lab.locator("section", has_text="Kit C")
    expect(slot).to_contain_text("DHL 42")
    expect(lab.locator("main")).not_to_contain_text(second.code)  # the next holder unseen
    slot.get_by_label("Condition").select_option("damaged")
    slot.get_by_label("What is damaged or missing").fill("MEMS 3 cable torn")
    slot.get_by_role("button", name="Log arrival").click()
    expect(lab.get_by_text("The arrival of Kit C is logged.")).to_be_visible()
    slot = lab.locator("section", has_text="Kit C")
    slot.get_by_label("Carrier and tracking number").fill("UPS 7")
    slot.get_by_role("button", name="Log dispatch").click()
    expect(lab.get_by_text("Kit C is logged as sent on.")).to_be_visible()
    shots(lab, "lab-kit-sent-on")
    arrival = Handover.objects.get(kit=kit, to_slot__participant=first)
    assert (arrival.condition, arrival.condition_note) == ("damaged", "MEMS 3 cable torn")

    page.reload()
    row = page.locator(f"#kit-{kit.pk} tbody tr").first
    expect(row).to_contain_text("MEMS 3 cable torn")
    expect(row.locator(".badge", has_text="damaged")).to_be_visible()
    shots(page, "coordinator-sees-the-damage")

    get_user_model().objects.create_user("other-coordinator", password=PASSWORD)
    other = Comparison.objects.create(code="OTHER-ROUND", title="Another round")
    other.coordinators.add(get_user_model().objects.get(username="other-coordinator"))
    stranger = new_context().new_page()
    _sign_in(stranger, base, "other-coordinator")
    response = stranger.goto(f"{base}/coordinator/{CODE}/kits/")
    assert response is not None and response.status == 404
    # the only errors: the 400 of the wrong plan and the 404 asked for above
    expected = ("status of 404", "plan/: Failed to load resource: the server responded with a "
                "status of 400")  # fmt: skip
    assert [e for e in console_errors if not any(x in e for x in expected)] == []
