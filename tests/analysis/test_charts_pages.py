"""The standard graphs on the results pages and their downloads (docs/domain.md §11,
docs/interfaces.md): the data read from the run equals the stored scores and results and
independent numpy computations; the page shows every chart with its caption and download
links; the downloads answer SVG and PNG as attachments to the round's coordinator and,
after publication, to its participants only."""

from __future__ import annotations

import itertools
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from django.utils.html import escape

from analysis import charts, graph_data
from analysis import standard_charts as std
from analysis.chart_specs import NAMES
from analysis.models import AssignedValue, Score
from labs.models import Membership, Participant
from proficiency.models import Comparison
from tests.analysis.test_web_numbers import CODE, C, login
from tests.factories import LaboratoryFactory, UserFactory

P = f"/results/{CODE}/"


def first_point(run) -> AssignedValue:
    found = AssignedValue.objects.filter(run=run).select_related("measurement_point__device")
    first = found.order_by("pk").first()
    assert first is not None
    return first


def test_chart_data_equals_the_stored_scores(run, demo):
    av = first_point(run)
    point = av.measurement_point
    data = graph_data.point_data(run, point)
    scores = {s.result.submission.participant.code: s for s in Score.objects.filter(
        run=run, result__measurement_point=point).select_related(
        "result__submission__participant")}  # fmt: skip
    assert data.labels == sorted(scores)
    # the z that counts: z′ where u(x_pt) > 0.3 σ_pt (ISO 13528 9.5), else z
    prime = av.sigma_pt is not None and av.standard_uncertainty > 0.3 * av.sigma_pt
    expected_z = [scores[c].z_prime if prime else scores[c].z for c in data.labels]
    assert data.z == pytest.approx(expected_z) and data.z_name == ("z′" if prime else "z")
    assert data.en == pytest.approx([scores[c].en for c in data.labels])
    # degrees of equivalence against numpy: d = x − x_pt, U(d) = 2·√(u² ± u²(x_pt))
    doe = data.doe()
    x = np.array([scores[c].result.value for c in data.labels])
    u = np.array([scores[c].result.expanded_uncertainty / scores[c].result.coverage_factor
                  for c in data.labels])  # fmt: skip
    applied = np.array([scores[c].correlation_applied for c in data.labels])
    assert doe.d == pytest.approx(x - av.value)
    assert doe.d == pytest.approx([scores[c].d for c in data.labels])
    u_pt2 = av.standard_uncertainty**2
    expected_u = 2 * np.sqrt(np.where(applied, u**2 - u_pt2, u**2 + u_pt2))
    assert doe.U_d == pytest.approx(expected_u)
    # k = 2 throughout: the stored En is d / U(d)
    assert {scores[c].result.coverage_factor for c in data.labels} == {2.0}
    assert doe.d / doe.U_d == pytest.approx([scores[c].en for c in data.labels])

    points = graph_data.run_points(run)
    pairs = graph_data.point_pairs(points)
    by_pk = {p.pk: p for p in points}
    expected = set()
    for a, b in itertools.combinations(points, 2):
        if (a.axis, a.frequency_hz) != (b.axis, b.frequency_hz):
            continue
        if a.device_id == b.device_id or (a.bench, a.direction) == (b.bench, b.direction):
            expected.add(frozenset((a.pk, b.pk)))  # benches or directions; or two devices
    assert {frozenset(int(i) for i in key.split("-")) for key, _ in pairs} == expected
    a, b = (by_pk[int(i)] for i in pairs[0][0].split("-"))
    assert a.device_id == b.device_id and a.bench != b.bench  # the two benches come first
    pair = graph_data.pair_data(run, a, b)
    values = {(s.result.submission.participant.code, s.result.measurement_point_id):
              s.result.value for s in Score.objects.filter(
              run=run, result__measurement_point__in=[a, b]).select_related(
              "result__submission__participant")}  # fmt: skip
    both = sorted(c for c, pk in values if pk == a.pk and (c, b.pk) in values)
    assert pair.labels == both and len(both) >= 3
    assert pair.x == [values[c, a.pk] for c in both] and pair.y == [values[c, b.pk] for c in both]

    mandel = graph_data.mandel_data(run)
    assert mandel.graph is not None
    j = [p.pk for p in points].index(point.pk)
    xs = np.array([scores[c].result.value for c in data.labels])
    h = (xs - xs.mean()) / xs.std(ddof=1)  # ISO 5725-2 7.3.3, independently
    rows = [mandel.labs.index(c) for c in data.labels]
    assert mandel.graph.h[rows, j] == pytest.approx(h)
    assert mandel.devices[j] == point.device.name

    lab = data.labels[0]
    overview = graph_data.lab_overview(run, lab)
    mine = Score.objects.filter(run=run, result__submission__participant__code=lab)
    assert len(overview.en) == mine.count()
    assert sorted(overview.en) == pytest.approx(sorted(s.en for s in mine))
    assert overview.groups == sorted(overview.groups)  # device · bench, in runs


def test_coordinator_page_shows_every_chart_with_caption_and_downloads(client, run):
    login(client, "coordinator")
    av = first_point(run)
    page = client.get(f"{C}charts/?point={av.measurement_point_id}").content.decode()
    for name in NAMES:
        if name != "overview":
            assert f'id="chart-{name}"' in page
            assert escape(std.CAPTIONS[name]) in page
    links = re.findall(r'href="(/coordinator/[^"]*/charts/[^"]+\.(?:svg|png)[^"]*)"', page)
    assert len(links) == 2 * (len(NAMES) - 1)
    assert '<select name="pair"' in page
    pair = re.search(r"charts/youden\.svg\?pair=(\d+)-(\d+)", page)
    assert pair and str(av.measurement_point_id) in pair.groups()  # a pair of the point
    for link in links:
        response = client.get(link.replace("&amp;", "&"))
        found = re.search(r"/charts/([\w-]+)\.(svg|png)", link)
        assert found is not None
        name, ext = found.groups()
        assert response.status_code == 200, link
        assert response["Content-Type"] == {"svg": "image/svg+xml", "png": "image/png"}[ext]
        disposition = response["Content-Disposition"]
        assert disposition.startswith(f'attachment; filename="{CODE}-{name}')
        assert disposition.endswith(f'.{ext}"')
        if name in ("point", "z", "density", "doe"):
            assert "mems-" in disposition and "-hz-" in disposition  # the point in the name
        if ext == "png":
            assert response.content.startswith(b"\x89PNG\r\n\x1a\n")
        else:
            root = ET.fromstring(response.content)
            assert root.tag.endswith("svg")
    lab = Participant.objects.filter(comparison=run.comparison).order_by("code")[0].code
    overview = client.get(f"{C}charts/overview.svg?lab={lab}")
    assert overview.status_code == 200 and f"{lab}: En and".encode() in overview.content
    missing = ("overview.svg", "overview.svg?lab=NOPE", "bogus.svg", "z.pdf", "z.svg?run=999999")
    for url in (f"{C}charts/{m}" for m in missing):
        assert client.get(url).status_code == 404, url


def test_participant_reads_its_overview_and_downloads_its_charts_highlighted(client, run, demo):
    participant = Participant.objects.filter(comparison=demo).order_by("code").first()
    assert participant is not None
    member = participant.laboratory.members.first()
    assert member is not None
    client.force_login(member.user)
    assert client.get(f"{P}charts/z.svg").status_code == 404  # not yet published
    Comparison.objects.filter(pk=demo.pk).update(status="published")
    page = client.get(P).content.decode()
    assert 'id="chart-overview"' in page and escape(std.CAPTIONS["overview"]) in page
    assert f"{P}charts/overview.svg" in page and f"{P}charts/overview.png" in page
    assert re.search(rf'href="{P}charts/\?point=\d+#chart-(z|en-bars)"', page)
    svg = client.get(f"{P}charts/overview.svg")
    assert svg.status_code == 200 and f"{participant.code}: En and".encode() in svg.content
    point = Score.objects.filter(run=run, result__submission__participant=participant).first()
    assert point is not None
    z = client.get(f"{P}charts/z.svg?point={point.result.measurement_point_id}")
    assert z.status_code == 200 and charts.OWN.encode() in z.content
    assert participant.code.encode() in z.content
    assert client.get(f"{P}charts/mandel-k.png").content.startswith(b"\x89PNG")
    assert client.get(f"{P}charts/overview.svg?lab=L99").status_code == 200  # its own only
    # a laboratory of another round (not in this one) sees nothing of it
    outsider = UserFactory.create(username="outsider")
    Membership.objects.create(user=outsider, laboratory=LaboratoryFactory.create(), role="staff")
    client.force_login(outsider)
    for url in (f"{P}charts/", f"{P}charts/z.svg", f"{P}charts/overview.png"):
        assert client.get(url).status_code == 404, url
