"""Measurement-point grid generation and the seed protocol templates (docs/domain.md §8)."""

import math

import pytest

from common.errors import ValidationFailed
from proficiency import protocols
from proficiency.models import MeasurementPoint
from proficiency.services import comparison_apply_template, measurement_points_generate
from tests.factories import ComparisonFactory, DeviceFactory

pytestmark = pytest.mark.django_db


def test_grid_is_the_full_product_and_idempotent(comparison):
    devices = [DeviceFactory.create(comparison=comparison, name=f"MEMS {i}") for i in (1, 2)]
    new = measurement_points_generate(
        comparison=comparison,
        devices=devices,
        axes=["X", "Y", "Z"],
        frequencies_hz=[5, 10, 20],
        benches=["linear", "curvilinear"],
    )
    # linear: 2 devices x 3 axes x 3 f x 1 direction; curvilinear: x 2 directions
    assert len(new) == 2 * 3 * 3 * 1 + 2 * 3 * 3 * 2 == 54
    assert comparison.measurement_points.count() == 54
    again = measurement_points_generate(
        comparison=comparison,
        devices=devices,
        axes=["X", "Y", "Z"],
        frequencies_hz=[5, 10, 20, 40],
        benches=["linear"],
    )
    assert len(again) == 2 * 3 * 1  # only the new 40 Hz linear points
    assert comparison.measurement_points.count() == 60
    dirs = set(comparison.measurement_points.values_list("bench", "direction"))
    assert dirs == {
        ("linear", "vertical"),
        ("curvilinear", "tangential"),
        ("curvilinear", "radial"),
    }


@pytest.mark.parametrize(
    "kwargs,message",
    [
        ({"axes": ["W"]}, "unknown axes ['W']"),
        ({"frequencies_hz": [0]}, "frequencies must be finite and > 0"),
        ({"frequencies_hz": [math.inf]}, "frequencies must be finite and > 0"),
        ({"benches": []}, "at least one bench"),
        ({"benches": ["linear"], "directions": ["radial"]}, "not possible on the linear bench"),
    ],
)
def test_grid_refuses_bad_lists(comparison, kwargs, message):
    device = DeviceFactory.create(comparison=comparison)
    args = dict(axes=["X"], frequencies_hz=[10], benches=["linear"]) | kwargs
    with pytest.raises(ValidationFailed, match=message.replace("[", r"\[").replace("]", r"\]")):
        measurement_points_generate(comparison=comparison, devices=[device], **args)
    assert MeasurementPoint.objects.count() == 0


def test_grid_refuses_device_of_another_comparison(comparison):
    foreign = DeviceFactory.create(comparison=ComparisonFactory.create())
    with pytest.raises(ValidationFailed, match="must belong to this comparison"):
        measurement_points_generate(
            comparison=comparison,
            devices=[foreign],
            axes=["X"],
            frequencies_hz=[5],
            benches=["linear"],
        )


def test_curvilinear_template_amplitudes_match_the_reference_data(comparison):
    device = DeviceFactory.create(comparison=comparison)
    comparison_apply_template(comparison=comparison, template_key="curvilinear", devices=[device])
    pts = comparison.measurement_points.filter(axis="X")
    amp = {(p.frequency_hz, p.direction): p.amplitude_m_s2 for p in pts}
    # reference-data/README.md: tangential 49.78, 48.73, 49.78; radial peaks 14.77, 5.53, 3.69
    expected = {
        (5.0, "tangential"): 49.78,
        (8.0, "tangential"): 48.73,
        (10.0, "tangential"): 49.78,
        (5.0, "radial"): 14.77,
        (8.0, "radial"): 5.53,
        (10.0, "radial"): 3.69,
    }
    assert amp.keys() == expected.keys()
    for key, value in expected.items():
        assert amp[key] == pytest.approx(value, abs=0.005), key
    assert comparison.protocol == "curvilinear"
    assert comparison.measurement_points.count() == 3 * 3 * 2


def test_linear_template_and_expected_components(comparison):
    device = DeviceFactory.create(comparison=comparison)
    comparison_apply_template(comparison=comparison, template_key="linear", devices=[device])
    freqs = sorted(set(comparison.measurement_points.values_list("frequency_hz", flat=True)))
    assert freqs == [5.0, 10.0, 20.0]
    assert set(comparison.measurement_points.values_list("amplitude_m_s2", flat=True)) == {10.0}
    # θ = 15°, α = 90°: a_x = 0, a_y = 10 sin 15° = 2.588, a_z = 10 cos 15° = 9.659
    ax, ay, az = protocols.linear_components(10.0, 15.0, 90.0)
    assert ax == pytest.approx(0.0, abs=1e-12)
    assert ay == pytest.approx(2.5881904510, rel=1e-10)
    assert az == pytest.approx(9.6592582629, rel=1e-10)
    # θ = 0°: only z is excited, with the full a_ref
    assert protocols.linear_components(10.0, 0.0, 270.0)[2] == 10.0


def test_unknown_template(comparison):
    with pytest.raises(ValidationFailed, match="Unknown protocol template 'rotary'"):
        comparison_apply_template(comparison=comparison, template_key="rotary", devices=[])
