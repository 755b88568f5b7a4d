"""The reports' standard graphs of ISO 13528:2022 §10 (docs/domain.md §9, §11): the kernel
density and the degrees of equivalence of the chart points and Mandel's h and k, drawn
with the web's figure builders from the numbers the web's charts read
(``analysis.graph_data``), each group with the pages' caption; the reader's own marks an
overlay in its own report only.  The demo round, analysed; PDF read back with pypdf."""

import io

import numpy as np
import pytest
from pypdf import PdfReader

from analysis import graph_data
from analysis import standard_charts as std
from analysis.reports import images as report_images
from analysis.reports import standard
from analysis.reports.assemble import clear_run_contexts, report_data
from analysis.reports.render import render_report
from analysis.services import analysis_run_execute, analysis_run_start
from labs.models import Laboratory, Participant
from tests.analysis.reports.conftest import pdf_text, words

pytestmark = pytest.mark.django_db


@pytest.fixture
def run(demo):
    run = analysis_run_start(comparison=demo, user=None)
    assert analysis_run_execute(run_id=run.pk) == "succeeded"
    run.refresh_from_db()
    clear_run_contexts()  # a fresh context: its charts are drawn (and seen) here
    return run


def spy(monkeypatch, name: str) -> list[tuple[tuple, dict]]:
    """The arguments of every call of ``standard_charts.<name>`` from now on."""
    calls: list[tuple[tuple, dict]] = []
    real = getattr(std, name)

    def recorded(*args, **kwargs):
        calls.append((args, kwargs))
        return real(*args, **kwargs)

    monkeypatch.setattr(std, name, recorded)
    return calls


def images(pdf: bytes) -> int:
    """The charts in the PDF: the image XObjects of each page, summed (pypdf)."""
    return sum(len(page.images) for page in PdfReader(io.BytesIO(pdf)).pages)


def web_point(run, data, index):
    """The run's measurement point of the report's point ``index``."""
    key = data.points[index].key
    return next(p for p in graph_data.run_points(run) if p.key == key)


def check_point_graphs(run, data, density_calls, doe_calls) -> None:
    """Each chart point's density and DoE drew graph_data.point_data's numbers."""
    assert len(density_calls) == len(doe_calls) == len(data.chart_points) > 0
    pairs = zip(density_calls, doe_calls, strict=True)
    for index, (dens, doe) in zip(data.chart_points, pairs, strict=True):
        web = graph_data.point_data(run, web_point(run, data, index))
        (values,), kwargs = dens
        np.testing.assert_allclose(values, web.values, rtol=1e-12, atol=0)
        assert kwargs["assigned_value"] == pytest.approx(web.assigned.value, rel=1e-12)
        assert kwargs["assigned_expanded_uncertainty"] == pytest.approx(
            web.assigned.expanded_uncertainty, rel=1e-12
        )
        (labels, d, big_u), _ = doe
        expected = web.doe()
        assert list(labels) == web.labels
        np.testing.assert_allclose(d, expected.d, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(big_u, expected.U_d, rtol=1e-12, atol=0)


def check_mandel(run, mandel_calls) -> int:
    """Mandel's h drawn per device equals graph_data.mandel_data's columns of the device;
    the number of charts."""
    web = graph_data.mandel_data(run)
    assert web.graph is not None
    devices = list(dict.fromkeys(web.devices))
    h_calls = [c for c in mandel_calls if c[1]["statistic"] == "h"]
    assert [c[1]["groups"][0] for c in h_calls] == devices
    for (labs, names, values, crit_5, crit_1), kwargs in h_calls:
        columns = [j for j, d in enumerate(web.devices) if d == kwargs["groups"][0]]
        assert list(labs) == web.labs and len(names) == len(columns)
        np.testing.assert_allclose(values, web.graph.h[:, columns], rtol=1e-12, equal_nan=True)
        np.testing.assert_allclose(crit_5, web.graph.h_critical_5[columns], rtol=1e-12)
        np.testing.assert_allclose(crit_1, web.graph.h_critical_1[columns], rtol=1e-12)
    # the demo's results carry no repeats: no k anywhere, said in one sentence
    assert not [c for c in mandel_calls if c[1]["statistic"] == "k"]
    return len(h_calls)


def test_participant_report_draws_the_webs_density_doe_and_mandel(run, monkeypatch):
    calls = {n: spy(monkeypatch, n) for n in ("density_figure", "doe_figure", "mandel_figure")}
    me = Participant.objects.filter(comparison=run.comparison).order_by("code")[0]
    data = report_data(run=run, participant=me)
    pdf = render_report(data)
    check_point_graphs(run, data, calls["density_figure"], calls["doe_figure"])
    n_mandel = check_mandel(run, calls["mandel_figure"])
    text = words(" ".join(pdf_text(pdf)))
    for caption in ("density", "doe", "mandel-h"):
        assert words(std.CAPTIONS[caption]) in text, caption
    assert f"Your result ({me.code}) is the pink tick." in text
    assert f"Yours ({me.code}) is drawn in pink." in text
    assert f"Your bars ({me.code}) are pink." in text
    assert "Mandel's k is not available: k needs repeat standard deviations" in text
    for lab in Laboratory.objects.all():
        assert lab.name not in text
    # the new charts: a density and a DoE per chart point, Mandel's h per device
    monkeypatch.setattr(standard, "point_graphs", lambda data: [])
    monkeypatch.setattr(standard, "mandel_graphs", lambda data: [])
    without = images(render_report(data))
    assert images(pdf) - without == 2 * len(data.chart_points) + n_mandel
    # the same bytes again, from the charts drawn once
    monkeypatch.undo()
    assert render_report(report_data(run=run, participant=me)) == pdf


def test_the_readers_marks_are_its_own_result(run):
    me = Participant.objects.filter(comparison=run.comparison).order_by("-code")[0]
    data = report_data(run=run, participant=me)
    flow = standard.point_graphs(data)
    marked = [f for f in _images(flow) if f.overlays]
    assert len(marked) == 2 * len(data.chart_points)  # its result at every chart point
    index = data.chart_points[0]
    rows = data.round.point_values[index]
    i = rows.labs.index(me.code)
    doe = report_images.round_charts(data)[("doe", index)]  # drawn by point_graphs above
    assert isinstance(doe, standard.DoEChart)
    mark = doe.overlay(i)
    assert mark is not None and mark.dots == (doe._px(i, doe.d[i]),)
    summary = report_data(run=run)
    assert not [f for f in _images(standard.point_graphs(summary)) if f.overlays]
    assert not [f for f in _images(standard.mandel_graphs(summary)) if f.overlays]


def _images(flow):
    """The chart images of a list of flowables, inside KeepTogether too."""
    for f in flow:
        inner = getattr(f, "_content", None)
        yield from (_images(inner) if inner is not None else [f] if hasattr(f, "raster") else [])


def test_summary_report_draws_them_for_its_chart_points_without_a_reader(run, monkeypatch):
    calls = {n: spy(monkeypatch, n) for n in ("density_figure", "doe_figure", "mandel_figure")}
    data = report_data(run=run)
    text = words(" ".join(pdf_text(render_report(data))))
    check_point_graphs(run, data, calls["density_figure"], calls["doe_figure"])
    check_mandel(run, calls["mandel_figure"])
    for caption in ("density", "doe", "mandel-h"):
        assert words(std.CAPTIONS[caption]) in text, caption
    assert "is the pink tick" not in text and "are pink" not in text
