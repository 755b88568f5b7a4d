"""The covariance of the linked degrees of equivalence (docs/domain.md §14; docs/interfaces.md
§3, §6): stored per run and point in its factored form and read back on PostgreSQL equal to
an independent dense solve of the bordered normal equations; shown to the coordinator on the
kits page (a matrix of r, or the largest pairs), in a CSV download, the archive, the API and
the summary report; never to a participant."""

from __future__ import annotations

import csv
import io
import re
from unittest.mock import patch

import numpy as np
import pytest
from rest_framework.test import APIClient

from analysis.api.views import CovariancePages
from analysis.archive_contents import Audience, archive_entries
from analysis.kit_results import COVARIANCE_COLUMNS, covariance_of, covariance_rows
from analysis.models import AnalysisRun, KitPointFit, KitScore
from analysis.reports.assemble import report_data
from analysis.reports.render import render_report
from common import numbers
from labs.models import Result
from proficiency.models import ComparisonStatus
from tests.analysis.kit_rounds import (
    PILOT_U,
    add_kit,
    analysed_with_coordinators,
    make_round,
    pilot_series,
    started,
)
from tests.analysis.reports.conftest import pdf_text
from tests.factories import MembershipFactory, UserFactory

pytestmark = pytest.mark.django_db

LOOPS = {"Kit A": ["L0", "L1", "L2", "L3"], "Kit B": ["L4", "L5", "L6"]}


def two_kits(capture, method: str = "reference") -> dict:
    """A pilot (L0) and six laboratories, Kit A (L1–L3) and Kit B (L4–L6), neither drifting:
    the observations are the results as stored and the pilot's repeats."""
    r = make_round(method=method)
    r["kits"] = [add_kit(r, "Kit A", r["labs"][:3]), add_kit(r, "Kit B", r["labs"][3:], offset=0.6)]
    return analysed_with_coordinators(r, capture, "cov", "OTHER-02")


@pytest.fixture
def pilot_round(django_capture_on_commit_callbacks):
    return two_kits(django_capture_on_commit_callbacks)


def dense_covariance(r: dict, point, reference: str) -> tuple[list[str], np.ndarray]:
    """The covariance of the participants' d written independently: unknowns K_A, K_B,
    b_L0 … b_L6 and b_T (the pilot's repeats, a series with its own offset); the design
    matrix of every observation, W = 1/u², the constraint (b_L0 = 0, or Σ w_j b_j = 0 over
    L0–L6 with w_j = 1/u_j²), the bordered system [[AᵀWA, c], [cᵀ, 0]] inverted by numpy,
    its b block.  The pilot under the pilot reference is left out, as stored."""
    found = Result.objects.filter(measurement_point=point).select_related("submission__participant")
    results = {x.submission.participant.code: x for x in found}
    codes = [f"L{i}" for i in range(7)]
    rows, u = [], []
    for kit_i, loop in enumerate(LOOPS.values()):
        for code in loop:
            rows.append((kit_i, 2 + codes.index(code)))
            u.append(results[code].expanded_uncertainty / 2)
        _, _, uu = pilot_series(r["kits"][kit_i], point)
        assert np.allclose(uu, PILOT_U / 2)
        for s in uu:
            rows.append((kit_i, 9))
            u.append(s)
    a = np.zeros((len(rows), 10))
    for n, (k, j) in enumerate(rows):
        a[n, k] = a[n, j] = 1.0
    w = 1.0 / np.asarray(u) ** 2
    c = np.zeros(10)
    if reference == "pilot":
        c[2] = 1.0
    else:
        c[2:9] = [1.0 / (results[code].expanded_uncertainty / 2) ** 2 for code in codes]
    kkt = np.zeros((11, 11))
    kkt[:10, :10] = a.T @ (w[:, None] * a)
    kkt[:10, 10] = kkt[10, :10] = c
    cov = np.linalg.inv(kkt)[2:9, 2:9]
    if reference == "pilot":
        return codes[1:], cov[1:, 1:]
    return codes, cov


def assert_equal_to_1e10(stored: np.ndarray, dense: np.ndarray) -> None:
    """Equal to 1e-10 relative, the entries near 0 (a correlation through the mean) taken
    relative to the largest."""
    np.testing.assert_allclose(stored, dense, rtol=1e-10, atol=1e-10 * np.abs(dense).max())


@pytest.mark.parametrize("method", ["reference", "weighted_mean"])
def test_stored_and_read_back_equal_a_dense_bordered_solve(django_capture_on_commit_callbacks,
                                                           method):  # fmt: skip
    r = two_kits(django_capture_on_commit_callbacks, method)
    reference = "pilot" if method == "reference" else "weighted_mean"
    assert not KitScore.objects.filter(run=r["run"]).exclude(u_drift=0).exists()  # no drift
    for point in r["points"]:
        fit = KitPointFit.objects.get(run=r["run"], measurement_point=point)  # from the database
        assert fit.reference == reference
        stored = fit.doe_covariance
        codes, dense = dense_covariance(r, point, reference)
        assert stored["codes"] == codes
        # the factored form: n own parts, n rows of kits + 1, (kits + 1)²
        assert len(stored["own"]) == len(stored["factor"]) == len(codes)
        assert {len(row) for row in stored["factor"]} == {3} and len(stored["core"]) == 3
        c = covariance_of(fit)
        assert c is not None and c.codes == codes
        assert_equal_to_1e10(c.covariance, dense)
        s = np.sqrt(np.diag(dense))
        assert_equal_to_1e10(c.correlation, dense / np.outer(s, s))
        # the diagonal is u²(d) as the scores store it
        for code, var in zip(codes, np.diag(c.covariance), strict=True):
            ks = KitScore.objects.get(run=r["run"], result__measurement_point=point,
                                      result__submission__participant__code=code)  # fmt: skip
            assert ks.linked_u == pytest.approx(np.sqrt(var), rel=1e-10)
    if reference == "pilot":  # two laboratories of one loop share their kit's value
        c = covariance_of(KitPointFit.objects.get(run=r["run"], measurement_point=r["points"][0]))
        assert c is not None
        rr = c.correlation
        i, j, k = (c.codes.index(x) for x in ("L1", "L2", "L5"))
        assert rr[i, j] > 0 and rr[i, j] > rr[i, k] >= 0


def test_a_round_of_one_kit_stores_no_covariance(django_capture_on_commit_callbacks):
    r = make_round()
    add_kit(r, "Kit A", r["labs"])
    run = started(r["comparison"], django_capture_on_commit_callbacks)
    fits = KitPointFit.objects.filter(run=run)
    assert fits.count() == 2 and all(f.doe_covariance == {} and f.reference == "" for f in fits)
    assert list(covariance_rows(run)) == []
    assert not any(e.name == "doe_covariance.csv" for e in archive_entries(Audience(run), []))


def csv_of(data: bytes) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(data.decode("utf-8-sig"))))


def test_the_archive_and_the_download_carry_the_long_form(client, pilot_round):
    r, run = pilot_round, pilot_round["run"]
    entries = {e.name: e for e in archive_entries(Audience(run), [])}
    out = io.BytesIO()
    entries["doe_covariance.csv"].write(out)
    rows = csv_of(out.getvalue())
    assert list(rows[0]) == COVARIANCE_COLUMNS
    assert len(rows) == 2 * (6 * 7 // 2)  # two points, six participants, pairs a ≤ b
    for point in r["points"]:
        codes, dense = dense_covariance(r, point, "pilot")
        mine = [x for x in rows if float(x["frequency_hz"]) == point.frequency_hz]
        assert {(x["device"], x["bench"], x["direction"], x["quantity"]) for x in mine} == {
            ("MEMS 1", point.bench, point.direction, "magnitude")}  # fmt: skip
        for x in mine:
            i, j = codes.index(x["code_a"]), codes.index(x["code_b"])
            assert i <= j
            assert float(x["covariance"]) == pytest.approx(dense[i, j], rel=1e-10)
            r_ij = dense[i, j] / np.sqrt(dense[i, i] * dense[j, j])
            assert float(x["correlation"]) == pytest.approx(r_ij, rel=1e-10, abs=1e-12)
    # the README names it; a participant's archive has none
    assert "doe_covariance.csv" in entries and "u²(d_a − d_b)" in entries["doe_covariance.csv"].what
    lab = r["labs"][1]
    assert "doe_covariance.csv" not in {e.name for e in archive_entries(Audience(run, lab), [])}
    # the kits page's download: the same rows
    code = r["comparison"].code
    client.force_login(r["coordinator"])
    response = client.get(f"/coordinator/{code}/results/kits/covariance.csv?run={run.pk}")
    assert response.status_code == 200
    assert csv_of(b"".join(response.streaming_content)) == rows
    # a ?run= that is not a run's id: the current run ("²".isdigit() is True, int("²")
    # fails; 20 digits overflow a bigint); another round's run or a run that is not: 404
    for junk in ("²", "１２", "99999999999999999999", "-1", "1e3"):
        response = client.get(f"/coordinator/{code}/results/kits/covariance.csv?run={junk}")
        assert response.status_code == 200, junk
        assert csv_of(b"".join(response.streaming_content)) == rows
    other_run = AnalysisRun.objects.exclude(comparison=r["comparison"]).first()
    for pk in ([other_run.pk] if other_run else []) + [run.pk + 10_000]:
        assert (
            client.get(f"/coordinator/{code}/results/kits/covariance.csv?run={pk}").status_code
            == 404
        )
    client.force_login(r["other"])
    assert client.get(f"/coordinator/{code}/results/kits/covariance.csv").status_code == 404


def member_of(r: dict, n: int, username: str):
    user = UserFactory.create(username=username)
    MembershipFactory.create(user=user, laboratory=r["labs"][n].laboratory)
    return user


def test_the_api_gives_them_to_the_coordinator_only(pilot_round):
    r = pilot_round
    url = f"/api/v1/comparisons/{r['comparison'].code}/doe-covariance/"
    api = APIClient()
    api.force_authenticate(r["coordinator"])
    answer = api.get(url)
    assert answer.status_code == 200
    body = answer.json()
    assert body["count"] == 2 and len(body["results"]) == 1  # one point per page
    item = body["results"][0]
    codes, dense = dense_covariance(r, r["points"][0], "pilot")
    assert item["codes"] == codes and item["reference"] == "pilot"
    assert (item["device"], item["frequency_hz"], item["quantity"]) == ("MEMS 1", 5.0, "magnitude")
    assert_equal_to_1e10(np.array(item["covariance"]), dense)
    assert item["correlation"][0][0] == 1.0
    both = api.get(url + "?page_size=5").json()["results"]
    assert [x["frequency_hz"] for x in both] == [5.0, 10.0]
    # a page holds no more matrix entries than its bound: 7 participants, 2 · 7² = 98 per
    # point, so a bound of 100 entries keeps one point a page whatever page_size asks
    with patch.object(CovariancePages, "max_entries", 100):
        capped = api.get(url + "?page_size=100").json()
    assert capped["count"] == 2 and len(capped["results"]) == 1 and capped["next"]
    ten = api.get(url + "?frequency_hz=10").json()["results"]
    assert [x["frequency_hz"] for x in ten] == [10.0]
    assert api.get(url + "?frequency_hz=ten").status_code == 400
    # another round's coordinator: 404; a participant, published or not: 403
    other = APIClient()
    other.force_authenticate(r["other"])
    assert other.get(url).status_code == 404
    lab = APIClient()
    lab.force_authenticate(member_of(r, 1, "cov-l2-member"))
    assert lab.get(url).status_code == 403
    c = r["comparison"]
    c.status = ComparisonStatus.PUBLISHED
    c.save(update_fields=["status"])
    assert lab.get(url).status_code == 403
    stranger = APIClient()
    stranger.force_authenticate(UserFactory.create(username="cov-stranger"))
    assert stranger.get(url).status_code == 404


def test_the_kits_page_shows_the_matrix_to_the_coordinator(client, pilot_round):
    r = pilot_round
    code = r["comparison"].code
    client.force_login(r["coordinator"])
    html = client.get(f"/coordinator/{code}/results/kits/").content.decode()
    assert "Correlations between degrees of equivalence" in html
    assert "u²(d<sub>a</sub>) + u²(d<sub>b</sub>) − 2·cov(d<sub>a</sub>, d<sub>b</sub>)" in html
    assert f"/coordinator/{code}/results/kits/covariance.csv?run={r['run'].pk}" in html
    _, dense = dense_covariance(r, r["points"][0], "pilot")
    s = np.sqrt(np.diag(dense))
    rr = dense / np.outer(s, s)
    # the first point's matrix: the row of L1, r to two decimals
    row = re.search(r'<th scope="row"><code>L1</code></th>(.*?)</tr>', html)
    assert row is not None
    cells = re.findall(r'<td class="num">([^<]*)</td>', row.group(1))
    assert cells == [numbers.fixed(x, 2) for x in rr[0]] and cells[0] == "1.00"
    # a participant's page: none of it
    c = r["comparison"]
    c.status = ComparisonStatus.PUBLISHED
    c.save(update_fields=["status"])
    client.force_login(member_of(r, 1, "cov-page-member"))
    mine = client.get(f"/results/{code}/kits/").content.decode()
    assert "Correlations between" not in mine and "covariance.csv" not in mine
    assert client.get(f"/coordinator/{code}/results/kits/covariance.csv").status_code == 404


def test_a_larger_round_shows_its_largest_pairs(client, pilot_round, monkeypatch):
    monkeypatch.setattr("analysis.kit_views.MATRIX_MAX", 3)
    r = pilot_round
    client.force_login(r["coordinator"])
    html = client.get(f"/coordinator/{r['comparison'].code}/results/kits/").content.decode()
    assert '<th scope="row">' not in html and "6 participants" in html
    codes, dense = dense_covariance(r, r["points"][0], "pilot")
    s = np.sqrt(np.diag(dense))
    rr = dense / np.outer(s, s)
    a, b = np.triu_indices(6, k=1)
    top = int(np.argmax(np.abs(rr[a, b])))
    first = re.search(r"<tbody><tr><td><code>(L\d)</code></td><td><code>(L\d)</code></td>"
                      r'<td class="num">([^<]*)</td>', html)  # fmt: skip
    assert first is not None
    assert first.groups() == (codes[a[top]], codes[b[top]], numbers.fixed(rr[a[top], b[top]], 2))


def test_the_summary_report_has_them_and_a_participants_report_none(pilot_round):
    r, run = pilot_round, pilot_round["run"]
    summary = "\n".join(pdf_text(render_report(report_data(run=run))))
    assert "Correlations r between the degrees of equivalence at MEMS 1" in summary
    assert "2·cov(d" in summary
    codes, dense = dense_covariance(r, r["points"][1], "pilot")
    s = np.sqrt(np.diag(dense))
    rr = dense / np.outer(s, s)
    line = " ".join(["L4", *(f"{x:.2f}" for x in rr[codes.index("L4")])])
    assert line in summary
    mine = "\n".join(pdf_text(render_report(report_data(run=run, participant=r["labs"][3]))))
    assert "Linking and drift" in mine and "Correlations" not in mine and "cov(d" not in mine
