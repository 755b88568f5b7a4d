"""analysis.standard_charts: the standard graphs draw the core's numbers (no database).

Each figure is read back through matplotlib's artists (bar heights, tick labels, line
data) and compared with an independent computation (numpy, scipy), and its SVG parsed."""

from __future__ import annotations

import math
import time
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from matplotlib.collections import LineCollection
from matplotlib.colors import to_hex
from scipy import stats

from analysis import charts
from analysis import standard_charts as std

LABS = ["L01", "L02", "L03", "L04", "L05", "L06"]
Z = [0.4, -2.5, 3.2, np.nan, -0.1, 1.9]


def ticks(ax) -> list[str]:
    return [t.get_text() for t in ax.get_xticklabels()]


def xs(line) -> np.ndarray:
    return np.asarray(line.get_xdata(), dtype=float)


def ys(line) -> np.ndarray:
    return np.asarray(line.get_ydata(), dtype=float)


def hex_of(colour) -> str:
    return to_hex(colour)


def bars(ax) -> tuple[list[float], list[str]]:
    return [p.get_height() for p in ax.patches], [to_hex(p.get_facecolor()) for p in ax.patches]


def test_z_bars_sorted_with_signal_colours_and_the_readers_own():
    fig = std.z_figure(LABS, Z, title="t", name="z′", highlight="L05")
    ax = fig.axes[0]
    order = np.argsort(np.array(Z)[[0, 1, 2, 4, 5]])  # NaN (L04) left out
    expected = [["L01", "L02", "L03", "L05", "L06"][i] for i in order]
    assert ticks(ax) == expected == ["L02", "L05", "L01", "L06", "L03"]
    heights, colours = bars(ax)
    assert heights == pytest.approx(sorted(v for v in Z if not math.isnan(v)))
    # -2.5 warning (amber), -0.1 the reader's own, 0.4 and 1.9 plain, 3.2 action (red)
    assert colours == [charts.WARN, charts.OWN, charts.LAB, charts.LAB, charts.BAD]
    lines = sorted(round(float(ys(line)[0]), 6) for line in ax.get_lines())
    assert lines == [-3, -2, 0, 2, 3]
    assert ax.get_ylabel() == "z′" and "not scored: 1" in ax.get_xlabel()
    svg = charts.render(fig, "inline")
    ET.fromstring(svg)
    # the codes are written in the sorted order
    assert [svg.index(code) for code in expected] == sorted(svg.index(c) for c in expected)


def test_signed_en_bars_sorted_with_the_limit():
    en = [0.3, -1.4, 0.9, 1.1]
    fig = std.en_bar_figure(LABS[:4], en, title="t", limit=1.0)
    heights, colours = bars(fig.axes[0])
    assert heights == sorted(en)
    assert colours == [charts.BAD, charts.LAB, charts.LAB, charts.BAD]
    assert ticks(fig.axes[0]) == ["L02", "L01", "L03", "L04"]


def test_youden_ellipse_is_the_95_percent_region_of_the_robust_covariance():
    rng = np.random.default_rng(7)
    x = 100 + rng.normal(size=15)
    y = 0.5 * (x - 100) + 100 + rng.normal(scale=0.5, size=15)
    labels = [f"L{i:02d}" for i in range(15)]
    fig = std.youden_figure(labels, x, y, assigned_x=100.0, assigned_y=100.2, x_label="a",
                            y_label="b", unit="mV", highlight="L03")  # fmt: skip
    ax = fig.axes[0]
    ring = next(line for line in ax.get_lines() if "ellipse" in str(line.get_label()))
    v = np.column_stack(ring.get_data())
    # independent: medians, MADe = 1.483·median|x − med|, Gnanadesikan–Kettenring r
    made = lambda a: 1.483 * np.median(np.abs(a - np.median(a)))  # noqa: E731
    c = np.array([np.median(x), np.median(y)])
    sx, sy = made(x), made(y)
    u, w = (x - c[0]) / sx, (y - c[1]) / sy
    r = (made(u + w) ** 2 - made(u - w) ** 2) / (made(u + w) ** 2 + made(u - w) ** 2)
    cov = np.array([[sx * sx, r * sx * sy], [r * sx * sy, sy * sy]])
    d2 = np.einsum("ij,jk,ik->i", v - c, np.linalg.inv(cov), v - c)
    assert d2 == pytest.approx(np.full(len(v), -2 * math.log(0.05)), rel=1e-3)
    assert "ellipse (robust)" in str(ring.get_label())
    crosses = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert {float(xs(line)[0]) for line in crosses} >= {100.0}
    own = [p for p in ax.collections if hex_of(p.get_facecolor()[0]) == charts.OWN]
    assert own and np.asarray(own[0].get_offsets()).tolist() == [[x[3], y[3]]]
    ET.fromstring(charts.render(fig, "inline"))


@pytest.mark.parametrize("n", [0, 1, 2])
def test_too_few_results_say_so(n):
    labels, values = LABS[:n], [100.0 + i for i in range(n)]
    youden = std.youden_chart(labels, values, values, assigned_x=100, assigned_y=100,
                              x_label="a", y_label="b", unit="mV")  # fmt: skip
    density = std.density_chart(values, assigned_value=100, assigned_expanded_uncertainty=1,
                                title="t", unit="mV")  # fmt: skip
    for svg in (youden, density):
        ET.fromstring(svg)
        assert "Too few" in svg and f": {n}; this graph needs at least 3" in svg
    drawn = (
        std.z_chart(labels, values, title="t"),
        std.doe_chart(labels, values, values, title="t", unit="mV"),
        std.en_bar_chart(labels, values, title="t"),
    )
    for svg in drawn:  # one or two labs draw; none says there is nothing
        ET.fromstring(svg)
        assert ("No " in svg) == (n == 0)


def test_identical_results_give_a_youden_plot_without_ellipse_and_no_density():
    same = [100.0] * 5
    fig = std.youden_figure(LABS[:5], same, same, assigned_x=100, assigned_y=100, x_label="a",
                            y_label="b", unit="mV")  # fmt: skip
    assert not any("ellipse" in str(line.get_label()) for line in fig.axes[0].get_lines())
    svg = std.density_chart(same, assigned_value=100, assigned_expanded_uncertainty=1,
                            title="t", unit="mV")  # fmt: skip
    assert "No density" in svg


def test_density_is_the_gaussian_kde_with_the_robust_bandwidth():
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.normal(100, 1, 20), rng.normal(106, 0.5, 6)])
    fig = std.density_figure(x, assigned_value=101.0, assigned_expanded_uncertainty=0.8,
                             title="t", unit="mV", own_value=float(x[2]))  # fmt: skip
    ax = fig.axes[0]
    curve = next(line for line in ax.get_lines() if line.get_label() == "kernel density")
    grid, f = curve.get_data()
    q1, q3 = np.quantile(x, [0.25, 0.75])
    sigma = min(1.483 * np.median(np.abs(x - np.median(x))), 0.7413 * (q3 - q1))  # C.2.2, C.2.3
    h = 0.9 * sigma * len(x) ** -0.2
    reference = stats.gaussian_kde(x, bw_method=h / np.std(x, ddof=1))(grid)
    assert f == pytest.approx(reference, rel=1e-3)
    own = next(line for line in ax.get_lines() if line.get_label() == "your result")
    assert hex_of(own.get_color()) == charts.OWN and xs(own)[0] == x[2]


def test_doe_bars_are_d_with_U():
    d, big_u = [1.0, -2.0, 0.5], [1.5, 1.0, 2.0]
    fig = std.doe_figure(LABS[:3], d, big_u, title="t", unit="mV", highlight="L02")
    ax = fig.axes[0]
    points = {hex_of(line.get_color()): ys(line).tolist() for line in ax.get_lines()
              if line.get_marker() == "o"}  # fmt: skip
    assert points == {charts.LAB: [1.0, 0.5], charts.OWN: [-2.0]}
    segments = [s for c in ax.collections if isinstance(c, LineCollection)
                for s in c.get_segments() if len(s) == 2 and s[0][0] == s[1][0]]  # fmt: skip
    spans = sorted((float(s[0][1]), float(s[1][1])) for s in segments)
    assert spans == sorted((v - u, v + u) for v, u in zip(d, big_u, strict=True))


def test_mandel_bars_grouped_by_point_with_indicator_lines():
    labs, points = ["A", "B", "C"], ["p1", "p2"]
    h = np.array([[1.0, np.nan], [-0.5, 0.2], [-0.5, -0.2]])
    fig = std.mandel_figure(labs, points, h, [1.15, np.nan], [1.15, np.nan], statistic="h",
                            groups=["MEMS 1", "MEMS 1"], highlight="B")  # fmt: skip
    ax = fig.axes[0]
    vlines = [c for c in ax.collections if isinstance(c, LineCollection)]
    tops = sorted(float(s[1][1]) for c in vlines[:2] for s in c.get_segments())
    assert tops == sorted(v for v in h.ravel() if not math.isnan(v))
    assert ticks(ax) == points
    dashed = [c for c in vlines[2:] if len(c.get_segments())]
    levels = sorted(float(s[0][1]) for c in dashed for s in c.get_segments())
    assert levels == [-1.15, -1.15, 1.15, 1.15]  # ± at 5 % and 1 %, at p1 only
    none = charts.render(std.mandel_figure(labs, points, np.full((3, 2), np.nan), [np.nan] * 2,
                         [np.nan] * 2, statistic="k", reasons=["unequal numbers of repeats",
                         None]), "inline")  # fmt: skip
    assert "not available: unequal numbers of repeats" in none


def test_mandel_point_names_stand_on_short_lines():
    """A point's label with its kind, upright under its bars, is broken at its "·" into
    lines of at most 24 characters, so the plot keeps its height (docs/domain.md §11.5)."""
    points = [
        "Z · 5 Hz · curvilinear tangential · angular-rate sensitivity",
        "Z · 10 Hz · linear vertical · sensitivity phase",
        "Z · 5 Hz · linear vertical",
    ]
    h = np.array([[1.0, 0.5, 0.2], [-0.5, -0.5, -0.1], [-0.5, 0.0, -0.1]])
    fig = std.mandel_figure(["A", "B", "C"], points, h, [1.15] * 3, [1.4] * 3, statistic="h")
    assert ticks(fig.axes[0]) == [
        "Z · 5 Hz\ncurvilinear tangential\nangular-rate sensitivity",
        "Z · 10 Hz\nlinear vertical\nsensitivity phase",
        "Z · 5 Hz\nlinear vertical",  # 26 characters
    ]  # fmt: skip


def test_lab_overview_groups_points_and_skips_missing_z():
    points = ["X 5 Hz up", "X 8 Hz up", "Y 5 Hz up"]
    fig = std.lab_overview_figure(points, ["MEMS 1 · linear"] * 2 + ["MEMS 2 · linear"],
                                  [0.3, 1.4, -0.2], [np.nan, 2.4, -3.1], code="L07")  # fmt: skip
    top, bottom = fig.axes
    assert bars(top) == ([0.3, 1.4, -0.2], [charts.LAB, charts.BAD, charts.LAB])
    assert bars(bottom) == ([2.4, -3.1], [charts.WARN, charts.BAD])
    assert ticks(bottom) == points
    svg = charts.render(fig, "inline")
    assert "MEMS 1 · linear" in svg and "MEMS 2 · linear" in svg and "L07" in svg


def test_a_thousand_labs_draw_quickly_and_write_only_the_readers_code():
    n = 1000
    codes = [f"L{i:04d}" for i in range(n)]
    rng = np.random.default_rng(1)
    v = 100 + rng.normal(size=n)
    start = time.process_time()
    out = [
        std.z_chart(codes, v - 100, title="t", highlight="L0421"),
        std.en_bar_chart(codes, (v - 100) / 2, title="t", highlight="L0421"),
        std.doe_chart(codes, v - 100, [0.5] * n, title="t", unit="mV", highlight="L0421"),
    ]
    seconds = time.process_time() - start
    print(f"three charts of {n} laboratories: {seconds:.2f} s")  # ~1 s on the CI machine
    assert seconds < 15
    for svg in out:
        ET.fromstring(svg)
        assert "L0421" in svg and "L0420" not in svg and "L0422" not in svg
    youden = std.youden_chart(codes, v, v + rng.normal(size=n), assigned_x=100, assigned_y=100,
                              x_label="a", y_label="b", unit="mV", highlight="L0421")  # fmt: skip
    assert "L0421" in youden and "L0420" not in youden


def test_png_and_svg_file_of_the_same_figure():
    fig = std.z_figure(LABS[:3], [0.1, 2.2, -3.5], title="t")
    png = charts.render(fig, "png")
    assert isinstance(png, bytes) and png.startswith(b"\x89PNG\r\n\x1a\n")
    width = int.from_bytes(png[16:20], "big")
    assert width == pytest.approx(5.6 * charts.PNG_DPI, abs=2)  # 150 dpi
    svg = charts.render(fig, "svg")
    assert isinstance(svg, str) and svg.startswith("<?xml")
    ET.fromstring(svg)
    assert charts.render(fig, "svg") == svg and charts.render(fig, "png") == png  # byte-stable


def test_every_chart_has_a_caption():
    from analysis.chart_specs import NAMES

    assert set(NAMES) == set(std.CAPTIONS)
    assert all(len(text) > 60 for text in std.CAPTIONS.values())


@pytest.mark.parametrize("n", [1, 2])
def test_overview_and_mandel_of_one_or_two_labs(n):
    labels = [f"L{i}" for i in range(n)]
    overview = std.lab_overview_chart(["X 5 Hz up"] * n, ["MEMS 1 · linear"] * n, [0.1] * n,
                                      [math.nan] * n, code="L0")  # fmt: skip
    assert "no z" in overview
    why = "h needs at least 3 laboratories"
    mandel = std.mandel_chart(labels, ["p"], [[math.nan]] * n, [math.nan], [math.nan],
                              statistic="h", reasons=[why])  # fmt: skip
    assert f"not available: {why}" in mandel
    for svg in (overview, mandel):
        ET.fromstring(svg)
