"""The front of a report worth signing: the performance summary first (the same counts
as the web's ``analysis.performance``), the coordinators by full name and role, the
provider's furniture (logo, address, accreditation; a header and "Page n of N" on every
page).  Read back with poppler (pdftotext -layout, pdfinfo, pdfimages)."""

import subprocess

import numpy as np
import pytest
from django.contrib.auth import get_user_model
from PIL import Image

from analysis.performance import lab_performance, performance
from analysis.reports.assemble import report_data
from analysis.reports.figures import youden_pair
from analysis.reports.render import render_report
from labs.models import Participant
from tests.analysis.reports.conftest import page_count, pdftotext, words
from tests.analysis.test_performance import varied  # noqa: F401  # the fixture

pytestmark = pytest.mark.django_db(transaction=True)


def squ(t) -> str:
    return f"{t.satisfactory} {t.warning} {t.action}"


def images_on(pdf: bytes, tmp_path, page: int | None = None) -> int:
    """Images drawn on ``page`` (every page: None), from poppler's pdfimages."""
    path = tmp_path / "report-for-images.pdf"
    path.write_bytes(pdf)
    pages = ["-f", str(page), "-l", str(page)] if page else []
    listed = subprocess.run(["pdfimages", "-list", *pages, str(path)],
                            check=True, capture_output=True).stdout.decode()  # fmt: skip
    return len(listed.splitlines()) - 2  # two header lines


def test_participant_report_opens_with_its_performance_summary(varied, tmp_path):  # noqa: F811
    run, code = varied
    participant = Participant.objects.get(comparison=run.comparison, code=code)
    pdf = render_report(report_data(run=run, participant=participant))
    first = words(pdftotext(pdf, tmp_path, 1, 1))
    web = lab_performance(run, code)
    assert web is not None
    t = web.total
    assert f"Performance summary of participant {code}" in first
    n = t.en.scored + t.en.not_scored
    assert (
        f"Of your {n} results, {t.en.satisfactory} are satisfactory in En (|En| ≤ 1) and "
        f"{t.en.action} unsatisfactory; the largest |En| is {web.max_abs_en:.2f}." in first
    )
    assert f"In z (or z′), {t.z.satisfactory} of {t.z.scored} are satisfactory" in first
    assert f"All results {n} {squ(t.en)} {squ(t.z)}" in first
    for _, heading, rows in web.breakdowns:
        for r in rows:
            m = r.en.scored + r.en.not_scored
            assert f"{heading} {r.level} {m} {squ(r.en)} {squ(r.z)}" in first, (heading, r)
    # the largest scores, as the web lists them: |En| first (the planted 7.50 on top)
    assert web.worst_en[0].en == -7.5
    listed = first.split("Largest scores Point Score Flag", 1)[1].lstrip()
    for s in web.worst_en:
        p = s.result.measurement_point
        where = f"{p.device.name}, {p.axis}, {p.frequency_hz:g} Hz, {p.bench} {p.direction}"
        assert listed.startswith(f"|En| {where} En {s.en:.2f} {s.flag} "), listed[:80]
        listed = listed.split(s.flag, 1)[1].lstrip()
    for s in web.worst_z:
        p = s.result.measurement_point
        kind = "z′" if s.z_is_prime else "z"  # type: ignore[attr-defined]  # annotations
        assert f"{p.bench} {p.direction} {kind} {s.z_used:.2f} {s.z_flag}" in listed  # type: ignore[attr-defined]
    # the 81 bullets of the old page are gone
    assert "Your result for" not in words(pdftotext(pdf, tmp_path))
    # the graphs: its En and z over its points, per chart point the results and the sorted
    # En and z (z at points with a σ_pt), the largest |En| per lab, a Youden plot (a pair of
    # its points where three participants have both), a frequency chart per device; per
    # chart point its kernel density and degrees of equivalence, and per device Mandel's h
    # (and k where the round has repeats)
    data = report_data(run=run, participant=participant)
    with_z = [p for p in data.chart_points
              if not np.isnan(data.round.point_scores[p].z).all()]  # fmt: skip
    devices = {p.device for p in data.points}
    youden = int(youden_pair(data) is not None)
    expected = 2 + 2 * len(data.chart_points) + len(with_z) + 1 + youden + len(devices)
    assert data.mandel is not None
    mandel = sum(bool(np.isfinite(s).any()) for s in (data.mandel.graph.h, data.mandel.graph.k))
    expected += 2 * len(data.chart_points) + mandel * len(devices)
    assert len(data.chart_points) == 4 and images_on(pdf, tmp_path) == expected


def test_summary_report_has_every_participants_counts(varied, tmp_path):  # noqa: F811
    run, code = varied
    pdf = render_report(report_data(run=run))
    text = words(pdftotext(pdf, tmp_path))
    head = text.index("Performance of the participants")
    assert head < text.index("1 Confidentiality")
    found = performance(run)
    assert len(found) == 12
    for lab in found:
        t = lab.total
        row = (f"{lab.code} {t.en.scored + t.en.not_scored} {squ(t.en)} {squ(t.z)} "
               f"{lab.max_abs_en:.2f} {lab.max_abs_z:.2f}")  # fmt: skip
        assert row in text, row
    planted = next(lab for lab in found if lab.code == code)
    assert planted.total.en.action >= 1 and planted.max_abs_en == 7.5  # the planted En


def test_coordinators_by_full_name_and_role(analysed, tmp_path):
    users = get_user_model()
    named = users.objects.get(username="coordinator")
    named.first_name, named.last_name = "Dr Ana", "Pérez"
    named.save()
    bare = users.objects.create_user("zz-second", password="x-Long-password-1")
    analysed.comparison.coordinators.add(bare)
    first = words(pdftotext(render_report(report_data(run=analysed)), tmp_path, 1, 1))
    assert "Coordinators Dr Ana Pérez, coordinator; zz-second, coordinator" in first
    assert "Coordinators coordinator" not in first


def test_provider_furniture_on_every_page(analysed, settings, tmp_path):
    logo = tmp_path / "logo.png"
    Image.new("RGB", (120, 40), (31, 58, 95)).save(logo)
    settings.PT_PROVIDER_NAME = "Vibration PT Ltd"
    settings.PT_PROVIDER_ADDRESS = "12 Quay Road, 4000 Porto"
    settings.PT_PROVIDER_ACCREDITATION = "accredited to ISO/IEC 17043 by IPAC, No. P-0042"
    settings.PT_PROVIDER_LOGO = str(logo)
    participant = analysed.comparison.participants.order_by("code").first()
    pdf = render_report(report_data(run=analysed, participant=participant))
    n = page_count(pdf, tmp_path)
    assert n > 3
    number = f"{analysed.comparison.code}-{participant.code}-v1"
    for page in range(1, n + 1):
        text = words(pdftotext(pdf, tmp_path, page, page))
        assert f"Vibration PT Ltd · {analysed.comparison.code} · report {number}" in text
        assert f"Page {page} of {n}" in text and "Preliminary report · issued" in text
    first = words(pdftotext(pdf, tmp_path, 1, 1))
    assert "Address 12 Quay Road, 4000 Porto" in first
    assert "Accreditation accredited to ISO/IEC 17043 by IPAC, No. P-0042" in first
    assert images_on(pdf, tmp_path, 1) == 1
    assert render_report(report_data(run=analysed, participant=participant)) == pdf  # stable
    # a logo that is not there: the same report without it, no error
    settings.PT_PROVIDER_LOGO = str(tmp_path / "gone.png")
    without = render_report(report_data(run=analysed, participant=participant))
    assert images_on(without, tmp_path, 1) == 0
    assert "Vibration PT Ltd" in pdftotext(without, tmp_path, 1, 1)
