"""Charts of many labs: the error bars and the |En| bars drawn as one collection
each give the same pixels as matplotlib's ``errorbar`` and ``bar`` (with the same "best"
legend position), and a chart's cost no longer grows like matplotlib's per-bar artists."""

import time

import numpy as np
import pytest

from analysis.reports import charts


def data(n: int, seed: int = 3) -> tuple[tuple[str, ...], tuple[float, ...], tuple[float, ...]]:
    rng = np.random.default_rng(seed)
    labs = tuple(f"L{i:05d}" for i in range(n))
    return labs, tuple((100 + rng.normal(0, 1, n)).tolist()), tuple(rng.uniform(1, 3, n).tolist())


def point(n: int) -> charts.PointChart:
    labs, values, expanded = data(n)
    return charts.PointChart(
        labs, values, expanded, x_pt=100.1, u_x_pt_expanded=0.4, title="MEMS 1, X", unit="mV"
    )


def en(n: int, seed: int) -> charts.EnChart:
    labs, values, _ = data(n, seed)
    return charts.EnChart(labs, tuple(abs(v - 100) for v in values), limit=1.0)


@pytest.mark.parametrize("n", [61, 400])
def test_collected_error_bars_draw_the_pixels_of_errorbar(monkeypatch, n):
    fast = point(n)
    monkeypatch.setattr(charts, "COLLECTED", 10**9)  # matplotlib's errorbar
    stock = point(n)
    assert fast.raster == stock.raster
    assert np.allclose(fast.to_px.get_matrix(), stock.to_px.get_matrix(), rtol=0, atol=0)
    assert fast.overlay("L00007") == stock.overlay("L00007")


# seed 4: bars tall enough that no legend position is free (the slow case of "best")
@pytest.mark.parametrize(("n", "seed"), [(61, 3), (400, 3), (400, 4), (3000, 4)])
def test_collected_en_bars_draw_the_pixels_of_bar_and_place_the_legend_alike(monkeypatch, n, seed):
    fast = en(n, seed)
    monkeypatch.setattr(charts, "COLLECTED", 10**9)  # matplotlib's bar
    stock = en(n, seed)
    assert fast.raster == stock.raster
    assert fast.overlay("L00042") == stock.overlay("L00042")


def test_en_chart_of_ten_thousand_labs_takes_well_under_a_second():
    """matplotlib's ``bar`` took ~11 s of CPU here (a Rectangle per bar, each tested by
    the "best" legend placement); the collection ~0.3 s."""
    started = time.process_time()
    chart = en(10_000, 4)
    assert time.process_time() - started < 3.0
    assert chart.overlay("L09999") is not None and chart.overlay("nobody") is None
