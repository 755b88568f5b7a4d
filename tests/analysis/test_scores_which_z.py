"""The scores page names the z that counts (ISO 13528 9.5: z′ where u(x_pt) > 0.3 σ_pt),
shows the flag of every score type, filters by flag and sorts by |En| or |z|."""

from __future__ import annotations

import re

from django.db.models.functions import Abs

from analysis.models import AssignedValue, Score
from tests.analysis.test_web_numbers import C, cells, login


def rows(page: str) -> list[list[str]]:
    body = page.split("<tbody>", 1)[1].split("</tbody>", 1)[0]
    return [cells(r) for r in re.findall(r"<tr[^>]*>.*?</tr>", body, re.S)]


def test_the_column_names_z_or_z_prime_by_the_rule(client, run):
    first, second = AssignedValue.objects.filter(run=run).order_by("pk")[:2]
    # u(x_pt) = 0.3 σ_pt exactly: z counts; u(x_pt) = 0.31 σ_pt: z′ counts
    AssignedValue.objects.filter(pk=first.pk).update(standard_uncertainty=1.5, sigma_pt=5.0)
    AssignedValue.objects.filter(pk=second.pk).update(standard_uncertainty=1.55, sigma_pt=5.0)
    login(client, "coordinator")
    for av, shown in ((first, "z"), (second, "z′")):
        at_point = Score.objects.filter(run=run, result__measurement_point=av.measurement_point)
        score = at_point.select_related("result__submission__participant").first()
        assert score is not None
        Score.objects.filter(pk=score.pk).update(z=2.5, z_prime=2.4, z_flag="warning")
        point = av.measurement_point
        page = client.get(C + "scores/", {
            "lab": score.result.submission.participant.code, "device": point.device.name,
            "axis": point.axis, "bench": point.bench, "direction": point.direction,
            "frequency_hz": repr(point.frequency_hz),
        }).content.decode()  # fmt: skip
        (row,) = rows(page)
        value = "2.50" if shown == "z" else "2.40"
        assert row[12:15] == [f"{shown} {value}", score.flag, "warning"], row
    assert "z′ replaces z where u(x_pt) > 0.3 σ_pt (ISO 13528 9.5)" in page


def test_filters_by_flag_and_sorts_by_abs_en(client, run):
    login(client, "coordinator")
    scores = Score.objects.filter(run=run)
    worst = scores.annotate(a=Abs("en")).order_by("-a").first()
    assert worst is not None
    flagged = scores.filter(flag=worst.flag).count()
    page = client.get(C + "scores/", {"flag": worst.flag, "order": "en"}).content.decode()
    assert f"{flagged} score" in page
    listed = rows(page)
    assert {r[13] for r in listed} == {worst.flag}
    shown = [abs(float(r[10].rstrip("†"))) for r in listed]
    assert shown == sorted(shown, reverse=True) and shown[0] == round(abs(worst.en), 2)
    by_z = rows(client.get(C + "scores/", {"order": "z"}).content.decode())
    zs = [abs(float(r[12].split()[1])) for r in by_z if r[12] != "—"]
    assert zs and zs == sorted(zs, reverse=True)
    # an unknown flag or order is ignored, as every filter of the page
    assert client.get(C + "scores/", {"flag": "bogus", "order": "x"}).status_code == 200


def test_downloads_and_the_api_name_the_z_that_counts(client, run):
    import csv
    import io

    first, second = AssignedValue.objects.filter(run=run, sigma_pt__isnull=False).order_by("pk")[:2]
    AssignedValue.objects.filter(pk=first.pk).update(standard_uncertainty=1.5, sigma_pt=5.0)
    AssignedValue.objects.filter(pk=second.pk).update(standard_uncertainty=1.55, sigma_pt=5.0)
    login(client, "coordinator")
    body = client.get(C + "scores.csv").content.decode()
    table = list(csv.DictReader(io.StringIO(body)))
    expected = {first.measurement_point_id: "z", second.measurement_point_id: "z_prime"}
    for av in (first, second):
        p = av.measurement_point
        rows_at = [r for r in table if r["device"] == p.device.name and r["axis"] == p.axis
                   and float(r["frequency_hz"]) == p.frequency_hz and r["bench"] == p.bench
                   and r["direction"] == p.direction]  # fmt: skip
        assert rows_at and {r["z_used"] for r in rows_at} == {expected[p.pk]}
    api = client.get(f"/api/v1/comparisons/{run.comparison.code}/scores/",
                     {"device": second.measurement_point.device.name,
                      "axis": second.measurement_point.axis,
                      "bench": second.measurement_point.bench,
                      "direction": second.measurement_point.direction,
                      "frequency_hz": repr(second.measurement_point.frequency_hz)})  # fmt: skip
    assert api.status_code == 200
    found = api.json()["results"]
    assert found and {r["z_used"] for r in found} == {"z_prime"}
