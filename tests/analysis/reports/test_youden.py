"""The participant report's Youden plot (docs/domain.md §9): a pair of the reader's points
ranked as the web ranks them (``analysis.graph_data.point_pairs``), the 95 % ellipse of
``analysis.core.graphs.youden_data``, the reader's point a pink overlay on a raster shared
by the run; the same bytes when rendered again."""

import subprocess

import numpy as np
import pytest

from analysis.core.graphs import youden_data
from analysis.reports import charts
from analysis.reports.assemble import report_data
from analysis.reports.figures import youden_pair
from analysis.reports.render import render_report
from analysis.services import analysis_run_execute, analysis_run_start
from analysis.standard_charts import CAPTIONS
from labs.models import Participant
from tests.analysis.reports.conftest import pdftotext, words

pytestmark = pytest.mark.django_db


@pytest.fixture
def run(demo):
    run = analysis_run_start(comparison=demo, user=None)
    assert analysis_run_execute(run_id=run.pk) == "succeeded"
    run.refresh_from_db()
    return run


def test_youden_plot_of_the_same_point_on_the_two_benches(run, tmp_path, monkeypatch):
    built = []
    real = charts.YoudenChart.__init__

    def spy(self, labels, x, y, **k):
        built.append((labels, x, y, k))
        real(self, labels, x, y, **k)

    monkeypatch.setattr(charts.YoudenChart, "__init__", spy)
    charts.youden_chart.cache_clear()
    # the reader: the first laboratory by name that measured on both benches (the bench
    # laboratories each ran one bench only; participant codes are drawn at random, so an
    # order by code would pick a different reader, and sometimes a one-bench one, each run)
    participants = Participant.objects.filter(comparison=run.comparison)
    readers = (
        report_data(run=run, participant=p)
        for p in participants.select_related("laboratory").order_by("laboratory__name")
    )
    data = next(
        d
        for d in readers
        if len({d.points[r.point].bench for r in d.results if r.lab == d.own_code}) > 1
    )
    me = next(p for p in participants if p.code == data.own_code)
    pair = youden_pair(data)
    assert pair is not None
    a, b = (data.points[i] for i in pair)
    # the web's first rank: one device, axis and frequency, measured on two benches
    assert (a.device, a.axis, a.frequency_hz) == (b.device, b.axis, b.frequency_hz)
    assert a.bench != b.bench
    pdf = render_report(data)
    assert render_report(report_data(run=run, participant=me)) == pdf
    ((labels, x, y, k),) = built  # one raster for the two renders
    at_a = {r.lab: r.value for r in data.results if r.point == pair[0]}
    at_b = {r.lab: r.value for r in data.results if r.point == pair[1]}
    both = sorted(set(at_a) & set(at_b))
    assert labels == tuple(both) and me.code in labels
    assert x == tuple(at_a[c] for c in both) and y == tuple(at_b[c] for c in both)
    assigned = {r.point: r.value for r in data.assigned}
    ref = youden_data(x, y, assigned[pair[0]], assigned[pair[1]])
    np.testing.assert_allclose(np.array(k["ring"]), ref.ellipse.vertices, rtol=1e-12)
    text = words(pdftotext(pdf, tmp_path))
    assert words(CAPTIONS["youden"]) in text
    assert f"Your result ({me.code}) is the pink dot." in text
    page = _page_of(pdf, tmp_path, f"Your result ({me.code}) is the pink dot.")
    path = tmp_path / "y.pdf"
    path.write_bytes(pdf)
    listed = subprocess.run(["pdfimages", "-list", "-f", str(page), "-l", str(page), str(path)],
                            check=True, capture_output=True).stdout.decode()  # fmt: skip
    assert len(listed.splitlines()) - 2 >= 1


def _page_of(pdf: bytes, tmp_path, needle: str) -> int:
    pages = pdftotext(pdf, tmp_path).split("\f")
    return next(i for i, t in enumerate(pages, start=1) if needle in words(t))
