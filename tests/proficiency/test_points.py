"""One measurement-point key and one label (common.points, docs/architecture.md §5): every
place that names a point says the same words, and the frequency is never rounded."""

from __future__ import annotations

import pytest

from analysis.forms import point_choice_label
from analysis.reports.data import PointInfo
from common.points import POINT_FIELDS, PointKey, format_number, point_label
from labs import importers
from labs.selectors import comparison_points, comparison_table
from tests.factories import ComparisonFactory, DeviceFactory, MeasurementPointFactory


def test_the_label_in_its_three_spellings():
    key = PointKey("MEMS 1", "X", 5.0, "linear", "vertical")
    assert point_label(key) == "MEMS 1, X, 5 Hz, linear vertical"
    assert point_label(key, sep=" · ") == "MEMS 1 · X · 5 Hz · linear vertical"
    assert point_label(key, sep=" ") == "MEMS 1 X 5 Hz linear vertical"
    assert point_label(key, device=False) == "X, 5 Hz, linear vertical"
    # a plain tuple in POINT_FIELDS order (the analysis groups' keys) reads the same
    assert point_label(key.measurand) == point_label(key)
    assert dict(zip(POINT_FIELDS, key.measurand, strict=True)) == {
        k: v for k, v in key._asdict().items() if k != "amplitude_m_s2"
    }


@pytest.mark.parametrize(
    ("frequency", "text"),
    [(5.0, "5"), (12.5, "12.5"), (0.4, "0.4"), (1234.5678, "1234.5678"), (1e6, "1000000")],
)
def test_the_frequency_is_written_in_full(frequency, text):
    """``:g`` wrote 1234.5678 Hz as "1234.57" and 10⁶ Hz as "1e+06": two points 1234.567
    and 1234.568 Hz had one label."""
    assert format_number(frequency) == text
    assert (
        point_label(("D", "Z", frequency, "linear", "vertical"))
        == f"D, Z, {text} Hz, linear vertical"
    )


def test_the_importers_key_is_the_one_key():
    assert importers.PointKey is PointKey


@pytest.mark.django_db
def test_every_place_names_a_point_alike():
    comparison = ComparisonFactory.create()
    device = DeviceFactory.create(comparison=comparison, name="MEMS 7")
    point = MeasurementPointFactory.create(
        comparison=comparison, device=device, axis="Y", frequency_hz=1234.5678,
        bench="curvilinear", direction="radial", amplitude_m_s2=None,
    )  # fmt: skip
    words = "MEMS 7, Y, 1234.5678 Hz, curvilinear radial"
    assert point.key == PointKey("MEMS 7", "Y", 1234.5678, "curvilinear", "radial", None)
    assert str(point) == words
    assert point_choice_label(point) == words.replace(", ", " · ")
    info = PointInfo(index=0, unit=device.unit, **point.key._asdict())
    assert (info.full_label, info.label) == (words, words.removeprefix("MEMS 7, "))
    # the selectors key the comparison's points by the same key the importers give a row
    assert comparison_points(comparison) == {point.key: point}
    assert comparison_table(comparison).point_ids == {point.key: point.pk}
