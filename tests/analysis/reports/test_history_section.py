"""The participant report's "Your results over the rounds" (docs/domain.md §9, §4.1): the
rounds and comparable points of ``analysis.history.lab_history`` for the reader's own
laboratory, never another laboratory's name or code; one sentence when the round is its
first.  Read back with poppler's pdftotext -layout."""

import io
from io import StringIO

import pytest
from django.core.management import call_command
from pypdf import PdfReader

from analysis.history import lab_history, round_date, trend_series
from analysis.history_chart import CAPTION as TREND_CAPTION
from analysis.reports import standard
from analysis.reports.assemble import report_data
from analysis.reports.render import render_report
from analysis.services import analysis_run_execute, analysis_run_start
from coordination.demo import LINEAR_LAB, PREVIOUS_CODE
from labs.models import Participant
from proficiency.models import Comparison, ComparisonStatus
from tests.analysis.reports.conftest import CODE, pdftotext, words

pytestmark = pytest.mark.django_db


def share(satisfactory: int, scored: int) -> str:
    return f"{satisfactory}/{scored} ({round(100 * satisfactory / scored)} %)"


@pytest.fixture
def two_rounds(demo_earlier_round):
    """The demo with IMU-2023-DEMO published (its latest run, no publication job) and
    IMU-2024-DEMO analysed."""
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    Comparison.objects.filter(code=PREVIOUS_CODE).update(status=ComparisonStatus.PUBLISHED)
    demo = Comparison.objects.get(code=CODE)
    run = analysis_run_start(comparison=demo, user=None)
    assert analysis_run_execute(run_id=run.pk) == "succeeded"
    run.refresh_from_db()
    return run


def _section(pdf: bytes, tmp_path) -> str:
    text = words(pdftotext(pdf, tmp_path))
    start = text.index("Your results over the rounds")
    return text[start : text.index("1 Confidentiality", start)]


def trend_drawn(monkeypatch) -> list[tuple]:
    """The data of every history trend chart drawn from now on (the web's builder)."""
    drawn: list[tuple] = []
    real = standard.history_figure

    def recorded(*args, **kwargs):
        drawn.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(standard, "history_figure", recorded)
    return drawn


def section_images(pdf: bytes) -> int:
    """The images on the pages of the history section (before "1 Confidentiality")."""
    reader = PdfReader(io.BytesIO(pdf))
    count = 0
    for page in reader.pages:
        count += len(page.images)
        if "1 Confidentiality" in page.extract_text():
            break
    return count


def test_history_lists_the_labs_rounds_codes_and_shares(two_rounds, tmp_path, monkeypatch):
    drawn = trend_drawn(monkeypatch)
    run = two_rounds
    me = Participant.objects.select_related("laboratory").get(
        comparison=run.comparison, laboratory__name=LINEAR_LAB[0]
    )
    history = lab_history(me.laboratory, until=round_date(run.comparison), run=run)
    assert [r.code for r in history.rounds] == [PREVIOUS_CODE, CODE]
    pdf = render_report(report_data(run=run, participant=me))
    section = _section(pdf, tmp_path)
    # the web's trend chart of the same numbers, under its caption (an image: none before)
    codes, en, z = trend_series(history.rounds, history.points)
    assert drawn == [(codes, en, z)]
    assert words(TREND_CAPTION) in section
    assert section_images(pdf) == 1
    for r in history.rounds:
        row = (
            f"{r.code} {r.date:%Y-%m-%d} {r.own_code} {r.en_scored} "
            f"{share(r.en_satisfactory, r.en_scored)} {share(r.z_satisfactory, r.z_scored)}"
        )
        assert row in section, row
    assert "Your laboratory took part in 2 rounds up to this one." in section
    for p in history.points:
        assert p.combined is not None
        assert f"{p.key.label} {p.n_rounds} {p.combined.rsz:.2f} {p.combined.rsz_flag}" in section
    assert "Your code is drawn anew in every round" in section
    others = Participant.objects.exclude(laboratory=me.laboratory).select_related("laboratory")
    mine = {r.own_code for r in history.rounds}
    for other in others:
        assert other.laboratory.name not in section
        if other.code not in mine:
            assert f" {other.code} " not in section, other.code


def test_a_first_round_says_so_in_one_sentence(demo, tmp_path, monkeypatch):
    drawn = trend_drawn(monkeypatch)
    run = analysis_run_start(comparison=demo, user=None)
    assert analysis_run_execute(run_id=run.pk) == "succeeded"
    run.refresh_from_db()
    me = Participant.objects.filter(comparison=demo).order_by("code").first()
    pdf = render_report(report_data(run=run, participant=me))
    section = _section(pdf, tmp_path)
    assert "This is the only round of your laboratory so far" in section
    assert "Comparable point" not in section
    assert drawn == [] and words(TREND_CAPTION) not in section
    assert section_images(pdf) == 0
