"""Seed protocols offer quantity kinds (docs/domain.md §8, §12): the linear and curvilinear
benches measure the magnitude and the phase, the rotating table also a gyroscope's angular
rate; a comparison asks for some of them, the magnitude by default."""

import pytest

from common.errors import ValidationFailed
from proficiency.services import comparison_apply_template, measurement_points_generate
from tests.factories import DeviceFactory

pytestmark = pytest.mark.django_db


def kinds(comparison):
    return sorted(set(comparison.measurement_points.values_list("bench", "quantity")))


def test_default_is_the_magnitude_as_before():
    device = DeviceFactory.create()
    c = device.comparison
    new = comparison_apply_template(comparison=c, template_key="linear_and_curvilinear",
                                    devices=[device])  # fmt: skip
    # 3 axes × (3 linear frequencies + 3 curvilinear × 2 directions)
    assert len(new) == 3 * (3 + 6)
    assert kinds(c) == [("curvilinear", "magnitude"), ("linear", "magnitude")]


def test_magnitude_and_phase_on_both_benches_angular_rate_on_the_table():
    device = DeviceFactory.create()
    c = device.comparison
    new = comparison_apply_template(comparison=c, template_key="linear_and_curvilinear",
                                    devices=[device], quantities=["magnitude", "phase",
                                                                  "angular_rate"])  # fmt: skip
    assert len(new) == 3 * (3 * 2 + 6 * 3)
    assert kinds(c) == [("curvilinear", "angular_rate"), ("curvilinear", "magnitude"),
                        ("curvilinear", "phase"), ("linear", "magnitude"),
                        ("linear", "phase")]  # fmt: skip
    again = comparison_apply_template(comparison=c, template_key="linear_and_curvilinear",
                                      devices=[device], quantities=["phase"])  # fmt: skip
    assert again == []  # idempotent


def test_a_kind_no_bench_offers_is_refused_and_nothing_is_made():
    device = DeviceFactory.create()
    c = device.comparison
    with pytest.raises(ValidationFailed, match="offers no angular_rate points"):
        comparison_apply_template(comparison=c, template_key="linear", devices=[device],
                                  quantities=["angular_rate"])  # fmt: skip
    with pytest.raises(ValidationFailed, match="unknown quantity 'foo'"):
        measurement_points_generate(comparison=c, devices=[device], axes=["X"],
                                    frequencies_hz=[5], benches=["linear"],
                                    quantities=["foo"])  # fmt: skip
    assert not c.measurement_points.exists()
