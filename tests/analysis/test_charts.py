"""analysis.charts: plain data in, deterministic inline SVG out (no database)."""

import xml.etree.ElementTree as ET
from typing import Any

from analysis import charts

LABS = ["L01", "L07", "L12"]


def parse(svg: str) -> ET.Element:
    assert svg.startswith("<svg")
    return ET.fromstring(svg)


def test_point_chart_has_labs_axis_labels_and_is_deterministic():
    kwargs: dict[str, Any] = dict(assigned_value=418.0, assigned_expanded_uncertainty=4.8,
                  title="MEMS 1 · X · 5 Hz", unit="D/(m/s^2)", highlight="L07")  # fmt: skip
    svg = charts.point_chart(LABS, [420.0, 421.5, 430.2], [8.0, 8.0, 9.0], **kwargs)
    parse(svg)
    for text in (*LABS, "Sensitivity (D/(m/s²))", "Participant", "x_pt"):
        assert text in svg
    assert charts.OWN in svg  # the own lab's colour
    assert svg == charts.point_chart(LABS, [420.0, 421.5, 430.2], [8.0, 8.0, 9.0], **kwargs)


def test_en_chart_marks_limit_and_outside_bars():
    svg = charts.en_chart(LABS, [0.2, -0.6, 1.7], title="En", limit=1.0)
    parse(svg)
    assert "En" in svg and all(lab in svg for lab in LABS)
    assert charts.BAD in svg  # the bar outside ±1 and the limit lines


def test_frequency_chart_series_and_nominal_band():
    series = [
        charts.Series("X", [5, 10, 20], [420.0, 421.0, 422.0], [5.0, 5.0, 5.0]),
        charts.Series("Y", [5, 8, 10], [419.0, 419.5, 420.0], [6.0, 6.0, 6.0]),
    ]
    svg = charts.frequency_chart(series, title="MEMS 1", unit="D/(m/s^2)", nominal=418.0,
                                 nominal_half_width=4.18)  # fmt: skip
    parse(svg)
    for text in ("Frequency (Hz)", "MEMS 1", "nominal ± tolerance", "X", "Y"):
        assert text in svg


def test_heatmap_prints_en_values_and_escapes_text():
    en = [[0.0, 0.25, 1.5], [0.25, 0.0, 0.1], [1.5, 0.1, 0.0]]
    svg = charts.heatmap(["X", "Y", "<b>Z</b>"], en, title="device=<MEMS 1>", highlight="Y")
    root = parse(svg)  # well-formed although a label contains markup
    assert "<b>" not in svg and "&lt;b&gt;" in svg
    assert "1.50" in svg and "0.25" in svg and "0.10" in svg
    assert root.get("aria-label") == "En matrix: device=<MEMS 1>"


def test_heatmap_large_matrix():
    n = 30
    levels = [f"L{i:02d}" for i in range(n)]
    en = [[abs(i - j) / 10 for j in range(n)] for i in range(n)]
    svg = charts.heatmap(levels, en, title="labs")
    parse(svg)
    assert "L29" in svg


def test_a_thousand_labs_chart_writes_only_the_readers_code_and_how_many():
    import time

    codes = [f"L{i:04d}" for i in range(1000)]
    values = [100.0 + (i % 7) * 0.1 for i in range(1000)]
    start = time.process_time()
    point = charts.point_chart(codes, values, [0.5] * 1000, assigned_value=100.2,
                               assigned_expanded_uncertainty=0.1, title="t", unit="mV",
                               highlight="L0421")  # fmt: skip
    en = charts.en_chart(codes, [(v - 100.2) / 0.5 for v in values], title="t",
                         highlight="L0421")  # fmt: skip
    assert time.process_time() - start < 10  # was 13 s of drawing; now well under 1 s
    for svg in (point, en):
        assert "L0421" in svg and "L0420" not in svg and "L0422" not in svg
        assert "Participant (1000, codes not written)" in svg
    small = charts.en_chart(codes[:80], [0.1] * 80, title="t", highlight="L0007")
    assert "L0006" in small and "L0079" in small  # up to MANY labs, every code


def test_a_value_axis_names_the_quantity_and_its_unit(monkeypatch):
    """Sensitivity for a magnitude as ever; a phase's and an angular rate's axis the kind's
    label, on the pages' charts and the reports' (not "Sensitivity (°)")."""
    from analysis.reports import charts as report_charts
    from analysis.standard_charts import density_figure

    assert charts.value_axis("D/(m/s^2)") == "Sensitivity (D/(m/s²))"
    assert charts.value_axis("deg", "phase") == "Sensitivity phase (°)"
    assert charts.value_axis("D/(deg/s)", "angular_rate") == "Angular-rate sensitivity (D/(°/s))"
    values = [1.2, 1.5, 1.4]
    fig = charts.point_figure(LABS, values, [0.2] * 3, assigned_value=1.4,
                              assigned_expanded_uncertainty=0.1, title="t", unit="deg",
                              quantity="phase")  # fmt: skip
    assert fig.axes[0].get_ylabel() == "Sensitivity phase (°)"
    fig = density_figure(values, assigned_value=1.4, assigned_expanded_uncertainty=0.1,
                         title="t", unit="deg", quantity="phase")  # fmt: skip
    assert fig.axes[0].get_xlabel() == "Sensitivity phase (°)"
    # a report's chart keeps its raster only: its axis read as it is frozen
    drawn: list[str] = []
    freeze = report_charts.Shared._freeze

    def frozen(self: report_charts.Shared) -> None:
        drawn.append(self.ax.get_ylabel())
        freeze(self)

    monkeypatch.setattr(report_charts.Shared, "_freeze", frozen)
    report_charts.PointChart(tuple(LABS), tuple(values), (0.2,) * 3, x_pt=1.4,
                             u_x_pt_expanded=0.1, title="t", unit="D/(deg/s)",
                             quantity="angular_rate")  # fmt: skip
    assert drawn == ["Angular-rate sensitivity (D/(°/s))"]
