"""Pages write numbers as a metrologist does (docs/domain.md §3.1): a value to the decimal
place of its uncertainty's second significant digit, scores as the PDF, the unit on the
column headings; float noise planted in the database never reaches the page."""

import re

from django.contrib.auth import get_user_model
from django.urls import reverse

from analysis.models import AssignedValue, Score
from common.quantities import unit_text
from labs.models import RawRecomputation, RawRecord, Result, Submission
from proficiency.models import Device

CODE = "IMU-2024-DEMO"
C = f"/coordinator/{CODE}/"
NOISE = re.compile(r"\d\.\d{10,}")  # ten decimals or more: float noise, not a measurement


def login(client, name):
    client.force_login(get_user_model().objects.get(username=name))


def heading(unit: str) -> str:
    """A column heading's unit as pages write it (``m/s²``: common.quantities.unit_text)."""
    return f' <span class="fw-normal text-nowrap d-block small">({unit_text(unit)})</span>'


def cells(page: str) -> list[str]:
    """The text of every table cell, tags stripped."""
    return [re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", page)]


def plant(result: Result, value: float, big_u: float) -> Result:
    Result.objects.filter(pk=result.pk).update(value=value, expanded_uncertainty=big_u)
    result.refresh_from_db()
    return result


def test_review_page_rounds_value_and_u_and_heads_columns_with_the_unit(client, demo):
    participant = demo.participants.get(laboratory__name__startswith="Alpine")
    submission = participant.submissions.get()
    Submission.objects.filter(pk=submission.pk).update(status="submitted")
    result = plant(submission.results.order_by("pk").first(), 3.4160160000000004, 0.0123)
    login(client, "coordinator")
    response = client.get(f"{C}review/{participant.code}/v{submission.version}/")
    assert response.status_code == 200
    page = response.content.decode()
    assert "3.4160160000000004" not in page and not NOISE.search(page)
    assert "3.416" in cells(page) and "0.012 (2)" in cells(page)
    assert f"Value{heading(result.unit)}</th>" in page
    assert f"U (k){heading(result.unit)}</th>" in page
    assert f"Others' median{heading(result.unit)}</th>" in page


def test_lab_version_page_rounds_u_and_puts_the_unit_in_the_headings(client, demo):
    participant = demo.participants.get(laboratory__name__startswith="Alpine")
    submission = participant.submissions.get()
    result = plant(submission.results.order_by("pk").first(), 637.5519116119091, 12.751038232238182)
    client.force_login(participant.laboratory.members.first().user)
    response = client.get(reverse("labs:submission", args=[CODE, submission.version]))
    assert response.status_code == 200
    page = response.content.decode()
    assert "12.751038232238182" not in page and not NOISE.search(page)
    rows = re.findall(r"<tr>.*?</tr>", page, re.S)
    row = next(r for r in rows if str(result.measurement_point) in r)
    assert cells(row)[:2] == ["638", "13"]
    assert f"Sensitivity{heading(result.unit)}</th>" in page
    assert f"U{heading(result.unit)}</th>" in page


def test_scores_page_writes_value_u_d_en_zeta_z_as_the_pdf(client, run):
    score = Score.objects.filter(run=run).select_related("result__submission__participant").first()
    assert score is not None
    plant(score.result, 3.4160160000000004, 0.0123)
    Score.objects.filter(pk=score.pk).update(
        d=12.3456, en=0.125, zeta=-1.23456789, z=2.0000000000000004, z_prime=1.999
    )
    point = score.result.measurement_point
    login(client, "coordinator")
    page = client.get(
        C + "scores/",
        {"lab": score.result.submission.participant.code, "device": point.device.name},
    ).content.decode()
    assert not NOISE.search(page)
    row = next(
        cells(r) for r in re.findall(r"<tr[^>]*>.*?</tr>", page, re.S) if "3.416" in cells(r)
    )
    # value, U, D to the value's place (its row's U, as the report), En (.2f, ties to
    # even as format()), ζ, and z′, the one that counts
    # here: u(x_pt) = 418 · 1 % / √3 = 2.41 > 0.3 σ_pt = 1.25 (σ_pt = 1 % of 418)
    assert row[7:13] == ["3.416", "0.012", "+12.346", "0.12", "-1.23", "z′ 2.00"]
    unit = point.device.unit
    assert f"Value{heading(unit)}</th>" in page and f"D{heading(unit)}</th>" in page
    # the download keeps full precision (docs/architecture.md §4)
    download = client.get(
        C + "scores.csv", {"lab": score.result.submission.participant.code}
    ).content.decode()
    assert "3.4160160000000004" in download and ",0.0123," in download
    assert ",-1.23456789," in download and ",12.3456," in download


def test_results_page_writes_assigned_values_by_their_u(client, run):
    a = AssignedValue.objects.filter(run=run).order_by("pk").first()
    assert a is not None
    AssignedValue.objects.filter(pk=a.pk).update(
        value=419.4712000000001, standard_uncertainty=0.06745, coverage_factor=2.0
    )  # U(x_pt) = 0.1349
    login(client, "coordinator")
    page = client.get(C + "results/").content.decode()
    assert "419.4712000000001" not in page and not NOISE.search(page)
    assert next(
        cells(r)[6:9] for r in re.findall(r"<tr>.*?</tr>", page, re.S) if "419.47" in r
    ) == ["419.47", "0.067", "0.13"]
    unit = a.measurement_point.device.unit
    assert f"x_pt{heading(unit)}</th>" in page and f"U(x_pt){heading(unit)}</th>" in page


# --- raw data and the comparison pages ------------------------------------------------------

NOISY = 3.4160160000000004  # 3.416016 after one float operation too many


def plant_raw(demo) -> tuple[RawRecord, Device]:
    """Noise in every number of the demo's raw records' recomputations, and in a device's
    nominal sensitivity and tolerance."""
    records = RawRecomputation.objects.filter(record__participant__comparison=demo)
    assert records.exists()
    records.update(
        status="succeeded", sensitivity=NOISY, expanded_uncertainty=0.012300000000000002,
        coverage_factor=2.0000000000000004, reported_value=NOISY + 0.002,
        reported_expanded_uncertainty=0.0123, reported_coverage_factor=2.0, en=0.12345678901234,
        fs_hz=1663.7012345678901, u_fs_hz=0.012345600000000001,
        budget=[{"name": "repeatability", "value": NOISY, "standard_uncertainty": 0.0123,
                 "contribution": 0.004560000000000001}],
    )  # fmt: skip
    device = demo.devices.order_by("name").first()
    assert device is not None
    device.nominal_sensitivity, device.tolerance = NOISY, 0.30000000000000004
    device.save()
    return records.get(record__data_name="demo-linear.bin").record, device


def no_noise(page: str) -> None:
    for noisy in ("3.4160160000000004", "3.418016", "0.012300000000000002", "2.0000000000000004",
                  "1663.7012345678901", "0.012345600000000001", "0.30000000000000004",
                  "0.004560000000000001", "0.12345678901234"):  # fmt: skip
        assert noisy not in page, noisy


def test_raw_data_pages_round_by_the_uncertainty(client, demo):
    record, _ = plant_raw(demo)
    client.force_login(record.participant.laboratory.members.order_by("pk")[0].user)
    listing = client.get(reverse("labs:raw_data", args=[CODE]))
    assert listing.status_code == 200
    page = listing.content.decode()
    no_noise(page)
    row = cells(page)
    # reported 3.418016 ± 0.0123 and recomputed 3.416016 ± 0.0123: to 0.001; En as 0.123
    assert {"3.418", "3.416", "0.123"} <= set(row), row
    detail = client.get(reverse("labs:raw_record", args=[CODE, record.pk]))
    assert detail.status_code == 200
    page = detail.content.decode()
    no_noise(page)
    assert {"3.418", "0.012 (2)", "3.416", "0.0046"} <= set(cells(page))
    assert 'data-testid="recomputed">3.416<' in page
    assert 'data-testid="en">0.123' in page
    assert 'data-testid="fs">1663.701 Hz (u = 0.012 Hz' in page
    login(client, "coordinator")
    review = client.get(f"{C}raw-data/")
    assert review.status_code == 200
    page = review.content.decode()
    no_noise(page)
    assert {"3.418", "0.012 (2)", "3.416", "0.0046"} <= set(cells(page))


def test_comparison_pages_write_nominal_values_without_noise(client, demo):
    _, device = plant_raw(demo)
    login(client, "coordinator")
    page = client.get(C).content.decode()
    no_noise(page)
    assert f"3.416016 {unit_text(device.unit)}" in cells(page)
    assert any(c.startswith("± 0.3 ") for c in cells(page))
    participant = demo.participants.get(laboratory__name__startswith="Alpine")
    client.force_login(participant.laboratory.members.first().user)
    lab_page = client.get(reverse("labs:comparison", args=[CODE])).content.decode()
    no_noise(lab_page)
    assert f"3.416016 {unit_text(device.unit)}" in cells(lab_page)
    assert any(c.startswith("± 0.3 ") for c in cells(lab_page))
