"""Charts are drawn once per analysis run and reader (docs/architecture.md §3.1): the
second request of a page draws nothing, a new run draws again, and one participant's
chart (its code highlighted) is never served to another."""

from __future__ import annotations

import re

import pytest

from analysis import charts
from analysis.models import AssignedValue, Score
from analysis.services import analysis_run_start
from labs.models import Participant
from proficiency.models import Comparison
from tests.analysis.test_web_numbers import CODE, C, login


@pytest.fixture
def drawn(monkeypatch):
    """Count the charts actually drawn (the real functions still draw them)."""
    calls: list[str] = []
    for name in ("point_chart", "en_chart", "frequency_chart", "heatmap"):
        real = getattr(charts, name)

        def spy(*args, _real=real, _name=name, **kwargs):
            calls.append(_name)
            return _real(*args, **kwargs)

        monkeypatch.setattr(charts, name, spy)
    return calls


def svgs(page: bytes) -> list[str]:
    return re.findall(r"<svg.*?</svg>", page.decode(), re.S)


def point_of(run) -> int:
    first = AssignedValue.objects.filter(run=run).order_by("pk").first()
    assert first is not None
    return first.measurement_point_id


def test_a_page_draws_its_charts_once_per_run(client, run, demo, drawn,
                                              django_capture_on_commit_callbacks):  # fmt: skip
    login(client, "coordinator")
    url = f"{C}charts/?point={point_of(run)}"
    first = svgs(client.get(url).content)
    n = len(drawn)
    assert {"point_chart", "en_chart", "frequency_chart"} <= set(drawn)
    assert len(first) >= 2
    assert svgs(client.get(url).content) == first and len(drawn) == n  # nothing drawn again
    client.get(C + "compatibility/")
    m = len(drawn)
    assert "heatmap" in drawn[n:]
    client.get(C + "compatibility/")
    assert len(drawn) == m
    with django_capture_on_commit_callbacks(execute=True):
        newer = analysis_run_start(comparison=demo, user=None)
    newer.refresh_from_db()
    assert newer.status == "succeeded"
    client.get(f"{C}charts/?point={point_of(newer)}")
    assert len(drawn) > m  # the new run's charts are its own


def test_one_participants_highlighted_chart_is_not_served_to_another(client, run, demo, drawn):
    Comparison.objects.filter(pk=demo.pk).update(status="published")
    point = point_of(run)
    url = f"/results/{CODE}/charts/?point={point}"
    # Two participants that both measured the point (a one-bench lab may not have).
    scored = Score.objects.filter(run=run, result__measurement_point_id=point)
    a, b = Participant.objects.filter(
        comparison=demo, pk__in=scored.values("result__submission__participant")
    ).order_by("code")[:2]
    pages = {}
    for p in (a, b):
        member = p.laboratory.members.first()
        assert member is not None
        client.force_login(member.user)
        pages[p.code] = client.get(url).content.decode()
    assert drawn.count("point_chart") == 2  # one per reader, not one for both
    for own, other in ((a.code, b.code), (b.code, a.code)):
        assert "Your code: " in pages[own]
        svg = pages[own].split('class="pt-chart"', 1)[1]
        assert "#d63384" in svg  # its own code highlighted ...
        assert own in svg and other in svg  # (codes are public within the round)
    assert pages[a.code] != pages[b.code]
