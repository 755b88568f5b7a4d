"""The demo's two-kit round of magnitude, phase and angular-rate points, IMU-2025-KITS, walked
as its people run it (docs/domain.md §12–§15): the coordinator reads the kits (Kit B
late back to the pilot); the pilot logs its arrival and its return; the coordinator runs the
analysis and reads a phase point's assigned value and a laboratory's D in degrees, the Kits
and linking tab's d and u_link, and the scores API with the quantity and u_link; after
publication a laboratory reads its own kit slot and results and no other laboratory's name;
another round's coordinator gets 404. Screenshots in test-artifacts/browser/<test>/."""

from __future__ import annotations

import math
import re

import pytest
from django.contrib.auth import get_user_model
from playwright.sync_api import Page, expect

from analysis.models import AnalysisRun, AssignedValue, KitScore, Score
from analysis.publication import publication_start
from coordination.demo import load_demo
from coordination.demo_kits import KITS_ROUND_CODE as CODE
from labs.models import Handover, Participant
from proficiency.models import Comparison
from tests.browser.test_two_bench_round import NOISE, PASSWORD, _sign_in

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

RATE_POINT = "IMU 1, Z, 5 Hz, curvilinear tangential, angular-rate sensitivity"


def _places(u: float) -> int:
    """The decimals of a number written to the second significant digit of ``u`` (§3.1)."""
    return 1 - math.floor(math.log10(u))


def _no_noise(page: Page) -> None:
    text = page.locator("main").inner_text()
    assert not NOISE.findall(text), f"{page.url}: {NOISE.findall(text)[:5]}"


def test_a_kit_round_of_three_kinds_from_the_kits_to_the_published_scores(
    page: Page, new_context, live_server, shots, console_errors, demo_kits_round
):
    load_demo(password=PASSWORD)
    kits = Comparison.objects.get(code=CODE)
    parts = {p.laboratory.name: p for p in Participant.objects.filter(comparison=kits)
             .select_related("laboratory")}  # fmt: skip
    pilot, last = parts["Elbe Calibration Services"], parts["Fjord Measurement Institute"]
    base = live_server.url

    # the coordinator's kits: Kit B has not reached the pilot's last slot
    _sign_in(page, base, "coordinator")
    page.goto(f"{base}/coordinator/{CODE}/kits/")
    for name in ("Kit A", "Kit B"):
        expect(page.get_by_role("heading", name=name)).to_be_visible()
    kit_b = kits.kits.get(name="Kit B")
    last_row = page.locator(f"#kit-{kit_b.pk} table").first.locator("tbody tr").last
    expect(last_row).to_contain_text(pilot.code)
    expect(last_row.locator(".badge", has_text="late")).to_be_visible()
    shots(page, "coordinator-kits")

    # the pilot logs Kit B's arrival, then sends it back to the provider
    lab = new_context().new_page()
    console_errors.watch(lab)
    _sign_in(lab, base, "lab07")
    lab.goto(f"{base}/lab/comparisons/{CODE}/")
    lab.get_by_role("link", name="Kit", exact=True).click()
    pending = lab.locator("section").filter(has=lab.get_by_role("button", name="Log arrival"))
    expect(pending).to_have_count(1)
    expect(pending).to_contain_text("Kit B")
    pending.get_by_label("Condition").select_option("good")
    pending.get_by_role("button", name="Log arrival").click()
    expect(lab.get_by_text("The arrival of Kit B is logged.")).to_be_visible()
    sending = lab.locator("section").filter(has=lab.get_by_role("button", name="Log dispatch"))
    expect(sending).to_have_count(1)
    sending.get_by_label("Carrier and tracking number").fill("DHL 7731")
    sending.get_by_role("button", name="Log dispatch").click()
    expect(lab.get_by_text("Kit B is logged as sent on.")).to_be_visible()
    shots(lab, "pilot-logs-kit-b")
    back = Handover.objects.get(kit=kit_b, to_slot__participant=pilot, from_slot__position=8)
    assert back.condition == "good" and back.received_at is not None
    home = Handover.objects.get(kit=kit_b, to_slot=None)
    assert home.from_slot is not None
    assert (home.carrier_note, home.from_slot.participant) == ("DHL 7731", pilot)

    # the coordinator runs the analysis (eager Celery: done when the page answers)
    page.goto(f"{base}/coordinator/{CODE}/")
    page.get_by_role("link", name="Run analysis…").click()
    page.get_by_role("button", name="Run analysis").click()
    expect(page.locator("#run-progress .badge")).to_have_text("Succeeded")
    run = AnalysisRun.objects.filter(comparison=kits).latest("pk")
    assert run.status == AnalysisRun.Status.SUCCEEDED
    page.get_by_role("link", name="See the results").click()

    # a phase point's assigned value: the pilot's, in degrees, to U's decimals
    phase = AssignedValue.objects.select_related("measurement_point__device").get(
        run=run, measurement_point__device__name="IMU 2", measurement_point__quantity="phase",
        measurement_point__frequency_hz=20.0,
    )  # fmt: skip
    pilot_phase = pilot.submissions.get().results.get(measurement_point=phase.measurement_point)
    # the reference laboratory's phase (through the circular mean: to rounding), −360°·f·1.1 ms
    assert phase.value == pytest.approx(pilot_phase.value, abs=1e-9) and -9 < phase.value < -7
    assert phase.expanded_uncertainty == pilot_phase.expanded_uncertainty
    row = page.locator("table tbody tr").filter(has_text="vertical · sensitivity phase")
    row = row.filter(has=page.locator("td", has_text=re.compile(r"^20$")))
    row = row.filter(has_text="IMU 2")
    # U = 0.xx° → x_pt to 0.01°
    shown_u = f"{pilot_phase.expanded_uncertainty:.2f}"
    expect(row).to_contain_text(f"{phase.value:.2f}°")  # no space before °
    expect(row).to_contain_text(shown_u)
    _no_noise(page)
    shots(page, "coordinator-assigned-values")

    # a laboratory's D at that phase point, in degrees, to its U's decimals
    score = Score.objects.select_related("result").get(
        run=run, result__submission__participant=last,
        result__measurement_point=phase.measurement_point,
    )  # fmt: skip
    assert score.d == pytest.approx(score.result.value - phase.value, abs=1e-9)
    assert abs(score.d) > 0.1  # a D that shows its sign
    page.goto(f"{base}/coordinator/{CODE}/scores/?quantity=phase&lab={last.code}")
    expect(page.locator("thead")).to_contain_text("D (°)")
    row = (
        page.locator("table tbody tr")
        .filter(has_text="IMU 2")
        .filter(has=page.locator("td", has_text=re.compile(r"^20$")))
    )
    decimals = _places(score.result.expanded_uncertainty)  # D to U's second digit
    expect(row).to_contain_text(f"{score.d:+.{decimals}f}")
    expect(row).to_contain_text(f"{score.result.value:.{decimals}f}")
    _no_noise(page)
    shots(page, "coordinator-phase-scores")

    # the Kits and linking tab: Kit B's drift corrected, a laboratory's linked d and u_link
    page.goto(f"{base}/coordinator/{CODE}/results/")
    page.get_by_role("link", name="Kits and linking").click()
    # a phase point is linked too, on its phases laid on a line (docs/domain.md §14)
    phase_row = page.locator("tr").filter(has_text="linear vertical, sensitivity phase")
    expect(phase_row.filter(has_text="pilot").first).to_be_visible()
    drift = page.locator("tr").filter(has_text=RATE_POINT).filter(has_text="Kit B")
    expect(drift.first).to_contain_text("drifting")
    at_rate = KitScore.objects.select_related("kit", "result__submission__participant").filter(
        run=run, kit__name="Kit B", result__measurement_point__device__name="IMU 1",
        result__measurement_point__quantity="angular_rate",
        result__measurement_point__frequency_hz=5.0,
    ).exclude(result__submission__participant=pilot)  # fmt: skip
    k = max(at_rate, key=lambda row: abs(row.linked_d or 0))  # the d that shows its sign
    linked = k.result.submission.participant
    assert k.drift_correction != 0 and k.u_drift > 0  # Kit B's IMU 1 gyroscope drifts
    assert k.linked_d is not None and k.linked_u is not None and k.u_link is not None
    big_u = 2 * k.linked_u
    assert 0.01 < big_u < 0.2  # U(d) of a rate near 14.3 D/(°/s): under 1.5 %
    mine = page.locator("tbody tr").filter(has_text=linked.code).filter(has_text=RATE_POINT)
    expect(mine).to_have_count(1)
    p = _places(big_u)  # d and U(d) to U(d)'s second significant digit, u_link to its own
    assert abs(k.linked_d) >= 10.0**-p
    expect(mine).to_contain_text(f"{k.linked_d:+.{p}f}")
    expect(mine).to_contain_text(f"{big_u:.{p}f}")
    expect(mine).to_contain_text(f"{k.u_link:.{_places(k.u_link)}f}")
    drift_places = _places(k.result.expanded_uncertainty)
    expect(mine).to_contain_text(f"{k.drift_correction:+.{drift_places}f}")
    _no_noise(page)
    shots(page, "coordinator-kits-and-linking")

    # the scores API: the kind and the link at full precision
    answer = page.request.get(
        f"{base}/api/v1/comparisons/{CODE}/scores/?lab={linked.code}&quantity=angular_rate"
    )
    assert answer.status == 200
    items = answer.json()["results"]
    assert len(items) == 6 and {i["quantity"] for i in items} == {"angular_rate"}
    (item,) = [i for i in items if i["device"] == "IMU 1" and i["frequency_hz"] == 5.0]
    assert (item["kit"], item["linked_d"], item["u_link"]) == ("Kit B", k.linked_d, k.u_link)
    assert item["drift_correction"] == k.drift_correction

    # published: the last laboratory reads its kit slot and its results, no one else's name
    publication_start(comparison=kits, user=None)
    kits.refresh_from_db()
    assert kits.status == "published"
    reader = new_context().new_page()
    console_errors.watch(reader)
    _sign_in(reader, base, "lab08")
    others = [name for name in parts if name != "Fjord Measurement Institute"]
    reader.goto(f"{base}/lab/comparisons/{CODE}/")
    text = reader.locator("main").inner_text()  # the round's description names no laboratory
    assert [n for n in others if n in text] == []
    reader.get_by_role("link", name="Kit", exact=True).click()
    slot = reader.locator("section", has_text="Kit B")
    expect(slot).to_have_count(1)
    expect(slot).to_contain_text("Received")
    expect(slot).to_contain_text("Sent on")
    text = reader.locator("main").inner_text()
    assert [n for n in others if n in text] == [] and pilot.code not in text
    shots(reader, "lab-kit-slot")
    reader.goto(f"{base}/results/{CODE}/scores/?quantity=phase&lab={last.code}")
    rows = reader.locator("table tbody tr")
    expect(rows).to_have_count(6)  # its own phases: the page's lab filter is its own code
    own = rows.filter(has_text="IMU 2").filter(
        has=reader.locator("td", has_text=re.compile(r"^20$"))
    )
    expect(own).to_contain_text(last.code)
    expect(own).to_contain_text(f"{score.d:+.{decimals}f}")
    reader.goto(f"{base}/results/{CODE}/scores/?quantity=phase")  # everyone's, by code
    expect(reader.locator("table tbody tr")).to_have_count(
        Score.objects.filter(run=run, result__measurement_point__quantity="phase").count()
    )
    text = reader.locator("main").inner_text()
    assert [n for n in others if n in text] == []
    _no_noise(reader)
    shots(reader, "lab-phase-scores")

    # another round's coordinator: 404
    get_user_model().objects.create_user("other-coordinator", password=PASSWORD)
    other = Comparison.objects.create(code="OTHER-ROUND", title="Another round")
    other.coordinators.add(get_user_model().objects.get(username="other-coordinator"))
    stranger = new_context().new_page()
    _sign_in(stranger, base, "other-coordinator")
    for path in ("kits/", "results/kits/", "scores/"):
        response = stranger.goto(f"{base}/coordinator/{CODE}/{path}")
        assert response is not None and response.status == 404, path
    assert [e for e in console_errors if "status of 404" not in e] == []
