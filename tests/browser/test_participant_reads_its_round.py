"""A participant reads its round as an assessor would, in the browser, on the demo with its
published earlier round: how it did first, its overview, the z and En bars and the Youden
plot of a point with captions, every chart downloadable as SVG and PNG, its history over
the demo's two rounds; and its PDF report opens with the same summary and holds the
graphs. Screenshots in test-artifacts/browser/<test>/ (looked at when the pages change)."""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from analysis.history import lab_history
from analysis.models import Report
from analysis.performance import lab_performance
from analysis.publication import publication_start
from analysis.services import analysis_run_start
from coordination.demo import load_demo
from labs.models import Participant
from proficiency.models import Comparison
from tests.browser.test_two_bench_round import PASSWORD, _sign_in

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

CODE = "IMU-2024-DEMO"
EARLIER = "IMU-2023-DEMO"


def _pdf_text(data: bytes) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        pdf = Path(tmp) / "r.pdf"
        pdf.write_bytes(data)
        out = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True,
                             check=True, text=True)  # fmt: skip
        return out.stdout


def test_a_participant_reads_how_it_did_its_graphs_and_its_history(
    page: Page, live_server, shots, console_errors, demo_earlier_round
):
    load_demo(password=PASSWORD)
    demo = Comparison.objects.get(code=CODE)
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    publication_start(comparison=demo, user=None)
    demo.refresh_from_db()
    assert demo.status == "published"
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
    expect(page.locator("#overview svg")).to_be_visible()
    shots(page, "results-how-it-did")

    # the bars of its largest |En|: the charts page of that point
    page.locator("a.point-bars").first.click()
    for name in ("z", "en-bars", "youden", "density", "doe"):
        figure = page.locator(f"#chart-{name}")
        expect(figure.locator("svg")).to_be_visible()
        expect(figure.locator("figcaption")).not_to_be_empty()
    shots(page, "charts-of-its-point")
    # every chart of the page downloads, as SVG and as PNG, named by round and chart
    links = page.locator("figure.pt-figure figcaption a")
    assert links.count() >= 2 * 8
    for i in range(links.count()):
        href = links.nth(i).get_attribute("href")
        assert href is not None
        response = page.request.get(base + href if href.startswith("/") else href)
        assert response.status == 200, href
        kind = response.headers["content-type"]
        assert kind in ("image/svg+xml", "image/png"), (href, kind)
        disposition = response.headers["content-disposition"]
        assert disposition.startswith("attachment") and CODE in disposition, disposition
        body = response.body()
        assert body.startswith(b"\x89PNG") if kind == "image/png" else b"<svg" in body[:400]

    # its history over the demo's two rounds, joined through the laboratory
    page.goto(f"{base}/lab/history/")
    history = lab_history(lab.laboratory)
    codes = {r.code: r.own_code for r in history.rounds}
    assert set(codes) == {EARLIER, CODE}  # a code is drawn per round: the two may agree
    main = page.locator("main")
    for round_code, own in codes.items():
        expect(main).to_contain_text(round_code)
        expect(main).to_contain_text(own)
    others = Participant.objects.filter(comparison__code=EARLIER).exclude(laboratory=lab.laboratory)
    text = main.inner_text()
    assert not [p.code for p in others if p.code not in codes.values() and f" {p.code} " in text]
    shots(page, "history-over-two-rounds")

    # the PDF opens with the same summary and holds the graphs
    report = Report.objects.filter(comparison=demo, participant=lab).latest("version")
    pdf = page.request.get(f"{base}/api/v1/reports/{report.token}/pdf")
    assert pdf.status == 200
    text = _pdf_text(pdf.body())
    first_page = " ".join(text.split("\f")[0].split())
    assert f"Performance summary of participant {lab.code}" in first_page
    assert f"results, {t.en.satisfactory} are satisfactory in En" in first_page
    assert console_errors == []
