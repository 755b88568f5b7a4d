"""The rendered PDFs: every item of docs/domain.md §9, the run's numbers, determinism, privacy."""

import math
import re
import subprocess
import sys

import pytest

from analysis.models import AssignedValue, Score
from analysis.reports.assemble import report_data
from analysis.reports.render import END_MARK, render_report
from common.numbers import round_to_uncertainty, value_with_uncertainty
from labs.models import Laboratory, Participant
from tests.analysis.reports.conftest import pdf_text

pytestmark = pytest.mark.django_db(transaction=True)
ORDER = (
    "measurement_point__device__name",
    "measurement_point__bench",
    "measurement_point__direction",
    "measurement_point__axis",
    "measurement_point__frequency_hz",
)
FLAGS = {"satisfactory", "questionable", "unsatisfactory", "action", "warning"}


def table_rows(text: str, codes: set[str]) -> list[list[str]]:
    """Rows of the results-and-scores tables: lab, value, U, k, D, En, ζ, z, flag (one
    extracted line per table row, the point label first where a point starts)."""
    body = text.split("6 Results and scores", 1)[1].split("7 Compatibility matrices", 1)[0]
    rows = []
    for line in body.splitlines():
        cells = line.split()[-9:]
        if len(cells) == 9 and cells[0] in codes and cells[8] in FLAGS | {"–"}:
            rows.append(cells)
    return rows


def close(printed: str, value: float, rel: float) -> bool:
    return math.isclose(float(printed), value, rel_tol=rel, abs_tol=0.006)


def test_summary_has_every_item_and_the_run_numbers(analysed, settings):
    pdf = render_report(report_data(run=analysed, authorised_by="Dr. Ada Lovelace"))
    pages = pdf_text(pdf)
    text = "\n".join(pages)
    code = analysed.comparison.code
    for item in (
        settings.PT_PROVIDER_NAME,
        "coordinator",
        f"{code}-S-v1",
        analysed.finished_at.strftime("%Y-%m-%d"),
        "Preliminary",
        "Dr. Ada Lovelace",
        "Confidentiality",
        "Scheme design and protocol",
        "Artefacts",
        "418 ± 1 %",
        "Participants",
        "Assigned values",
        "Metrological traceability",
        "u(x_pt)",
        "σ_pt",
        "ζ",
        "Results and scores",
        "Compatibility matrices",
        "Graphs",
        "No comments.",
        "Conclusion",
        "Nominal value with tolerance",
        "Homogeneity",
        "stability",
    ):
        assert item in text, item
    codes = set(analysed.comparison.participants.values_list("code", flat=True))
    assert len(codes) == 12
    assert all(re.search(rf"\b{c}\b", text) for c in codes)
    for number, page in enumerate(pages, start=1):
        assert f"Page {number} of {len(pages)}" in page
    assert END_MARK in pages[-1] and all(END_MARK not in p for p in pages[:-1])

    scores = list(
        Score.objects.filter(run=analysed)
        .order_by(*(f"result__{o}" for o in ORDER), "result__submission__participant__code")
        .values_list(
            "result__submission__participant__code",
            "result__value",
            "result__expanded_uncertainty",
            "d",
            "en",
            "zeta",
        )
    )
    rows = table_rows(text, codes)
    assert len(rows) == len(scores) == 891
    for row, (lab, value, big_u, d, en, zeta) in zip(rows, scores, strict=True):
        assert row[0] == lab
        # GUM 7.2.6: U to two significant digits, the value and D to U's last digit
        assert (row[1], row[2]) == value_with_uncertainty(value, big_u)
        assert row[4] == round_to_uncertainty(d, big_u, sign=True)
        assert close(row[5], en, 0) and close(row[6], zeta, 0)


def test_assigned_values_printed(analysed):
    text = "\n".join(pdf_text(render_report(report_data(run=analysed))))
    body = text.split("5 Assigned values", 1)[1].split("6 Results and scores", 1)[0]
    # a label wider than its column is wrapped, its lines extracted apart from its row's
    row = re.compile(r"^MEMS \d+ (?:[XYZ], [\d.]+ Hz, \w+ \w+ )?(\S+) (\S+) ")
    printed = [m.groups() for line in body.splitlines() if (m := row.match(line.strip()))]
    found = AssignedValue.objects.filter(run=analysed).order_by(*ORDER)
    stored = list(found.values_list("value", "standard_uncertainty"))
    assert len(printed) == len(stored) == 81
    for (x, u), (value, unc) in zip(printed, stored, strict=True):
        assert (x, u) == value_with_uncertainty(value, unc)


def test_rendering_is_byte_identical(analysed):
    data = report_data(run=analysed)
    first, second = render_report(data), render_report(data)
    assert first == second and first.startswith(b"%PDF")


def test_participant_report_names_no_laboratory(analysed):
    participant = Participant.objects.get(
        comparison=analysed.comparison, laboratory__name="Alpine Vibration Metrology"
    )
    pdf = render_report(report_data(run=analysed, participant=participant))
    text = "\n".join(pdf_text(pdf))
    assert f"Participant report for participant {participant.code}" in text
    for lab in Laboratory.objects.all():
        assert lab.name not in text
        assert not lab.contact_email or lab.contact_email not in text
    own = Score.objects.filter(run=analysed, result__submission__participant=participant)
    assert own.count() == 81
    flat = " ".join(text.split())
    bad = sum(abs(s.en) > 1 for s in own)
    assert f"Performance summary of participant {participant.code}" in flat
    assert f"Of your 81 results, {81 - bad} are satisfactory in En (|En| ≤ 1) and {bad} " in flat


def test_render_modules_import_no_django():
    code = (
        "import sys, analysis.reports.render, analysis.reports.data;"
        "bad = [m for m in sys.modules if m == 'django' or m.startswith('django.')];"
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_assembly_takes_a_few_queries(analysed, django_assert_max_num_queries):
    participant = analysed.comparison.participants.first()
    # 13: the consistency tests take two (the reasons at every point, the findings where a
    # test signals); 4 more: the laboratory's history (analysis.history: participations,
    # publications, the latest runs of rounds without one, scores); 2 more, once per run:
    # Mandel's h and k as the web reads them (analysis.graph_data.mandel_data: the run's
    # points, every result's mean and repeat standard deviation); 2 more: the demo's kits,
    # their fits and every result's kit row (docs/domain.md §13, §14); 1 more: the
    # covariances of the linked degrees of equivalence (read once per run, for the summary)
    with django_assert_max_num_queries(13 + 4 + 2 + 2 + 1):
        data = report_data(run=analysed, participant=participant)
    assert len(data.scores) == 891 and len(data.points) == 81 and data.own_code
