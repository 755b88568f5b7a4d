"""A linked round's kits shown (docs/domain.md §13, §14; docs/interfaces.md §3): the
coordinator's "Kits and linking" page with d, U(d), u_link written as §3.1 says, the API's
added keys at full precision, the reports' "Linking and drift" part; another round's
coordinator gets 404, a participant sees its own numbers only."""

from __future__ import annotations

import re

import pytest
from rest_framework.test import APIClient

from analysis.models import KitScore
from analysis.reports.assemble import clear_run_contexts, report_data
from analysis.reports.render import render_report
from common import numbers
from labs.models import Result
from proficiency.models import ComparisonStatus
from tests.analysis.kit_rounds import add_kit, analysed_with_coordinators, make_round, started
from tests.analysis.reports.conftest import pdf_text
from tests.factories import MembershipFactory, UserFactory

pytestmark = pytest.mark.django_db


@pytest.fixture
def linked(django_capture_on_commit_callbacks):
    r = make_round()
    add_kit(r, "Kit A", r["labs"][:3])
    add_kit(r, "Kit B", r["labs"][3:], drift=0.02, offset=0.6)
    return analysed_with_coordinators(r, django_capture_on_commit_callbacks, "kit", "OTHER-01")


def row_of(r, code, point=0) -> KitScore:
    return KitScore.objects.select_related("kit").get(
        run=r["run"], result__measurement_point=r["points"][point],
        result__submission__participant__code=code,
    )  # fmt: skip


def test_the_coordinator_reads_every_participants_link(client, linked):
    client.force_login(linked["coordinator"])
    code = linked["comparison"].code
    results = client.get(f"/coordinator/{code}/results/")
    assert results.status_code == 200 and "Kits and linking" in results.content.decode()
    page = client.get(f"/coordinator/{code}/results/kits/")
    assert page.status_code == 200
    html = page.content.decode()
    k = row_of(linked, "L5")
    assert k.linked_d is not None and k.linked_u is not None and k.u_link is not None
    big_u = 2 * k.linked_u
    assert numbers.round_to_uncertainty(k.linked_d, big_u, sign=True) in html
    assert numbers.uncertainty(big_u) in html and numbers.uncertainty(k.u_link) in html
    assert numbers.round_to_uncertainty(k.drift_correction, k.result.expanded_uncertainty,
                                        sign=True) in html  # fmt: skip
    assert "Kit B" in html and "drifting" in html and "the pilot" in html


def test_another_rounds_coordinator_gets_404(client, linked):
    client.force_login(linked["other"])
    code = linked["comparison"].code
    assert client.get(f"/coordinator/{code}/results/kits/").status_code == 404
    api = APIClient()
    api.force_authenticate(linked["other"])
    assert api.get(f"/api/v1/comparisons/{code}/scores/").status_code == 404


def test_the_api_carries_the_link_at_full_precision(linked):
    api = APIClient()
    api.force_authenticate(linked["coordinator"])
    code = linked["comparison"].code
    answer = api.get(f"/api/v1/comparisons/{code}/scores/?lab=L5&frequency_hz=5")
    assert answer.status_code == 200
    (item,) = answer.json()["results"]
    k = row_of(linked, "L5")
    assert item["kit"] == "Kit B"
    assert item["linked_d"] == k.linked_d and item["u_link"] == k.u_link
    assert k.linked_u is not None and item["linked_expanded_uncertainty"] == 2 * k.linked_u
    assert item["drift_correction"] == k.drift_correction != 0 and item["u_drift"] == k.u_drift


def test_a_participant_sees_its_own_link_only(linked):
    c = linked["comparison"]
    c.status = ComparisonStatus.PUBLISHED
    c.save(update_fields=["status"])
    own = linked["labs"][1]  # L2
    member = UserFactory.create(username="l2-member")
    MembershipFactory.create(user=member, laboratory=own.laboratory)
    api = APIClient()
    api.force_authenticate(member)
    answer = api.get(f"/api/v1/comparisons/{c.code}/scores/?lab=L5")  # asks for another's
    assert answer.status_code == 200
    items = answer.json()["results"]
    assert {i["lab"] for i in items} == {"L2"} and len(items) == 2
    assert all(i["linked_d"] is not None and i["kit"] == "Kit A" for i in items)
    client = APIClient()
    client.force_login(member)
    assert client.get(f"/coordinator/{c.code}/results/kits/").status_code == 404
    assert "Kits and linking" in client.get(f"/results/{c.code}/").content.decode()
    page = client.get(f"/results/{c.code}/kits/")
    assert page.status_code == 200
    html = page.content.decode()
    for point in (0, 1):
        k = row_of(linked, "L2", point)
        assert k.linked_d is not None and k.linked_u is not None
        assert numbers.round_to_uncertainty(k.linked_d, 2 * k.linked_u, sign=True) in html
    # the round's figures, and of the laboratories its own code only: no other's kit or date
    assert "Kit B" in html and "drifting" in html and "Your results" in html
    assert set(re.findall(r"<code[^>]*>(L\d+)</code>", html)) == {"L2"}
    assert "Messages of the run" not in html


def test_the_reports_say_what_was_done(linked):
    run = linked["run"]
    summary = "\n".join(pdf_text(render_report(report_data(run=run))))
    assert "Linking and drift" in summary and "the pilot" in summary
    assert re.search(r"2\s+drifting", summary)  # Kit B at both points
    # the artefacts paragraph points at the pilot's repeats, never "no measurements"
    flat = " ".join(summary.split())
    assert "Homogeneity: the artefacts travelled in 2 kits" in flat
    assert "Stability: the pilot measured each kit repeatedly over its circulation (4 " in flat
    assert "no measurements of the pilot" not in flat
    # the pilot is the reference: its row says so instead of a u_link of 0
    table = flat[flat.find("Lab Kit Points linked") :]
    assert re.search(r"\bL0 Kit A 2 0 reference – L1 ", table), table[:300]
    k5 = row_of(linked, "L5")
    largest = max(row_of(linked, "L5", p).u_link or 0 for p in (0, 1))
    assert numbers.uncertainty(largest) in summary
    own = linked["labs"][4]  # L5
    mine = "\n".join(pdf_text(render_report(report_data(run=run, participant=own))))
    assert "Linking and drift" in mine
    assert k5.linked_d is not None and k5.linked_u is not None
    assert numbers.round_to_uncertainty(k5.linked_d, 2 * k5.linked_u, sign=True) in mine
    other = row_of(linked, "L2")
    assert other.linked_d is not None and other.linked_u is not None
    table = mine[mine.find("Lab Device Point Kit") : mine.find("4 Participants")]
    assert "L2 " not in table and "L5 " in table


def test_the_schema_names_the_added_keys():
    schema = APIClient().get("/api/schema/?format=json").json()
    keys = {"kit", "linked_d", "linked_expanded_uncertainty", "u_link", "drift_correction",
            "u_drift"}  # fmt: skip
    assert keys <= schema["components"]["schemas"]["Score"]["properties"].keys()
    run_keys = schema["components"]["schemas"]["RunParameters"]["properties"]
    assert "drift_treatment" in run_keys


def test_chi2_is_written_to_three_significant_digits(client, linked):
    from analysis.models import KitPointFit

    client.force_login(linked["coordinator"])
    fit = KitPointFit.objects.get(run=linked["run"], measurement_point=linked["points"][0])
    assert fit.chi2 is not None and fit.dof == 6
    html = client.get(f"/coordinator/{linked['comparison'].code}/results/kits/").content.decode()
    assert f'<td class="num">{numbers.significant(fit.chi2, 3)}</td>' in html


@pytest.fixture
def two_kinds():
    """A kit round of a magnitude (point 0) and an angular rate (point 1, in D/(deg/s)): Kit A
    with the first three laboratories, Kit B (offset, no drift) with the other four; not yet
    analysed."""
    r = make_round()
    rate = r["points"][1]
    rate.quantity = "angular_rate"
    rate.save(update_fields=["quantity"])
    Result.objects.filter(measurement_point=rate).update(unit="D/(deg/s)")
    add_kit(r, "Kit A", r["labs"][:3])
    add_kit(r, "Kit B", r["labs"][3:], offset=0.6)
    return r


def test_a_table_of_two_kinds_writes_each_rows_unit(
    client, two_kinds, django_capture_on_commit_callbacks
):
    """A kit round of a magnitude and an angular rate: the participants' table has no one
    unit, so a Unit column gives each row's (its headings once said each row had its own
    and only d showed it)."""
    r = two_kinds
    coordinator = UserFactory.create()
    r["comparison"].coordinators.add(coordinator)
    r["run"] = started(r["comparison"], django_capture_on_commit_callbacks)
    client.force_login(coordinator)
    html = client.get(f"/coordinator/{r['comparison'].code}/results/kits/").content.decode()
    table = html[html.index("Each participant's kit") :]
    table = table[: table.index("</table>")]
    head = table[: table.index("</thead>")]
    # a Unit column (the d, U(d), u_link and drift of a row are all in it); none per cell
    assert '<th scope="col">Unit</th>' in head and "(unit in each row)" not in head
    assert "text-body-secondary" not in table
    rows = re.findall(r"<tr>(.*?)</tr>", table[table.index("<tbody>") :], re.S)
    for point, unit in ((0, "D/(m/s²)"), (1, "D/(°/s)")):  # stored D/(deg/s), shown with °
        k = row_of(r, "L5", point)
        assert k.linked_d is not None and k.linked_u is not None
        d = numbers.round_to_uncertainty(k.linked_d, 2 * k.linked_u, sign=True)
        mine = [x for x in rows if "<code>L5</code>" in x and f'<td class="num">{d}</td>' in x]
        assert len(mine) == 1 and f'<td class="text-nowrap">{unit}</td>' in mine[0]


def test_the_summary_report_gives_the_largest_u_link_per_unit(
    two_kinds, django_capture_on_commit_callbacks
):
    """A kit round of a magnitude and an angular rate: the summary report's largest u_link of
    a laboratory is one per unit, named (a magnitude's D/(m/s^2) and an angular rate's
    D/(deg/s), written D/(°/s), are not compared); a round of one unit keeps its bare number
    (above)."""
    r = two_kinds
    run = started(r["comparison"], django_capture_on_commit_callbacks)
    clear_run_contexts()
    summary = " ".join("\n".join(pdf_text(render_report(report_data(run=run)))).split())
    r["run"] = run
    per_unit = [row_of(r, "L5", p).u_link for p in (0, 1)]
    assert all(u is not None for u in per_unit)
    row = summary[summary.index("L5 Kit B") : summary.index("L6 Kit B")]
    cells = {f"{numbers.uncertainty(per_unit[0])} D/(m/s²)",
             f"{numbers.uncertainty(per_unit[1])} D/(°/s)"}  # fmt: skip
    assert all(c in row for c in cells) and row.count("; ") == 1


HEADING = '{} <span class="fw-normal text-nowrap d-block small">({})</span>'


def test_slopes_and_kit_values_carry_their_unit(client, linked):
    """A round of one unit: the slope's heading is the point's unit per day, D/(m/s²)
    written with ², the kit values' the unit itself, on the results' kits page, on the
    coordinator's kits page (with the kit's value and largest u_stab) and in the report."""
    client.force_login(linked["coordinator"])
    code = linked["comparison"].code
    html = client.get(f"/coordinator/{code}/results/kits/").content.decode()
    assert HEADING.format("Slope", "(D/(m/s²))/d") in html
    assert HEADING.format("u(slope)", "(D/(m/s²))/d") in html
    assert HEADING.format("Kit values (u)", "D/(m/s²)") in html
    assert "m/s^2" not in html and "(unit in each row)" not in html.split("Participants")[0]
    kits = client.get(f"/coordinator/{code}/kits/")
    assert kits.status_code == 200
    page = kits.content.decode()
    for heading in ("Value", "Largest u_stab"):
        assert HEADING.format(heading, "D/(m/s²)") in page
    assert HEADING.format("Slope", "(D/(m/s²))/d") in page and "m/s^2" not in page
    summary = " ".join(" ".join(pdf_text(render_report(report_data(run=linked["run"])))).split())
    assert "Slope ((D/(m/s²))/d)" in summary and "u(slope) ((D/(m/s²))/d)" in summary
    assert "m/s^2" not in summary  # the artefacts' unit too


def test_a_table_of_two_kinds_writes_each_slopes_unit(client, django_capture_on_commit_callbacks):
    """A magnitude and a phase: no one unit, so each slope and kit value names its own (a
    phase's in °/d and °), on both pages and in the report."""
    r = make_round()
    phase = r["points"][1]
    phase.quantity = "phase"
    phase.save(update_fields=["quantity"])
    Result.objects.filter(measurement_point=phase).update(unit="deg", value=1.5)
    add_kit(r, "Kit A", r["labs"][:3])
    add_kit(r, "Kit B", r["labs"][3:], offset=0.6)
    coordinator = UserFactory.create()
    r["comparison"].coordinators.add(coordinator)
    run = started(r["comparison"], django_capture_on_commit_callbacks)
    client.force_login(coordinator)
    code = r["comparison"].code
    html = client.get(f"/coordinator/{code}/results/kits/").content.decode()
    drift = html[html.index("Drift per kit and point") : html.index("Link per point")]
    assert drift.count("(unit in each row)") == 2
    assert drift.count('secondary">°/d</span>') == 4
    assert drift.count('secondary">(D/(m/s²))/d</span>') == 4
    link = html[html.index("Link per point") : html.index("Each participant")]
    assert link.count('text-body-secondary">°</span>') == 2  # one per kit at the phase
    assert link.count("D/(m/s²)</span>") == 2
    # the coordinator's kits page, wider per row: a Unit column, the slopes in unit/d
    page = client.get(f"/coordinator/{code}/kits/").content.decode()
    tables = [t[: t.index("</table>")] for t in page.split("<table")[1:]]
    stability = [t for t in tables if "Drift of" in t]
    assert len(stability) == 2  # one per kit
    for t in stability:
        head = t[: t.index("</thead>")]
        assert '<th scope="col">Unit</th>' in head and head.count("(unit/d)") == 2
        assert "(unit in each row)" not in head and "secondary" not in t  # no unit per cell
        units = re.findall(r'<td class="text-nowrap">([^<]*)</td><td class="num">', t)
        assert units == ["D/(m/s²)", "°"]  # the magnitude's row, then the phase's
    clear_run_contexts()
    summary = " ".join(" ".join(pdf_text(render_report(report_data(run=run)))).split())
    assert summary.count(" °/d") == 4 and summary.count(" (D/(m/s²))/d") == 4
