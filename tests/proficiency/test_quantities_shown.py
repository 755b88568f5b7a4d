"""A quantity kind and its unit as a metrologist reads them (docs/domain.md §2, §3.1): the
registry's label where a point's label names the kind, degrees as ``°`` with no space after
the number; what is stored, downloaded and accepted on input keeps ``deg``."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from django.template import Context, Template

from analysis.reports.data import PointInfo
from common import quantities
from common.points import PointKey, group_text, point_label

RATE = PointKey("IMU 1", "Z", 10.0, "curvilinear", "tangential", None, "angular_rate")
PHASE = PointKey("IMU 1", "Z", 5.0, "linear", "vertical", None, "phase")
MAGNITUDE = PointKey("IMU 1", "Z", 5.0, "linear", "vertical")


def test_a_point_label_names_the_kind_by_the_registrys_label():
    assert point_label(RATE) == "IMU 1, Z, 10 Hz, curvilinear tangential, angular-rate sensitivity"
    assert point_label(PHASE, sep=" · ") == "IMU 1 · Z · 5 Hz · linear vertical · sensitivity phase"
    assert point_label(PHASE, sep=" ") == "IMU 1 Z 5 Hz linear vertical sensitivity phase"
    assert point_label(MAGNITUDE) == "IMU 1, Z, 5 Hz, linear vertical"  # as before kinds
    assert [quantities.label_shown(k) for k in (None, "", *quantities.NAMES)] == [
        "", "", "", "sensitivity phase", "angular-rate sensitivity"
    ]  # fmt: skip


def test_a_report_label_of_another_kind_names_its_unit():
    """The report's tables give numbers without units and the artefacts' table gives the
    device's: a phase's or an angular rate's label says its own."""
    rate = PointInfo(index=0, unit="D/(deg/s)", **RATE._asdict())
    phase = PointInfo(index=1, unit="deg", **PHASE._asdict())
    magnitude = PointInfo(index=2, unit="D/(m/s^2)", **MAGNITUDE._asdict())
    assert rate.label == "Z, 10 Hz, curvilinear tangential, angular-rate sensitivity (D/(°/s))"
    assert phase.full_label == "IMU 1, Z, 5 Hz, linear vertical, sensitivity phase (°)"
    assert magnitude.label == "Z, 5 Hz, linear vertical"


@pytest.mark.parametrize(
    ("stored", "shown"),
    [
        ("deg", "°"),
        ("D/(deg/s)", "D/(°/s)"),
        ("D/(m/s^2)", "D/(m/s²)"),
        ("mV/(m/s^2)", "mV/(m/s²)"),
        ("m^-1", "m⁻¹"),
        ("mg/LSB", "mg/LSB"),
        ("", ""),
    ],
)
def test_a_unit_is_shown_with_the_degree_sign(stored, shown):
    assert quantities.unit_text(stored) == shown


def test_no_space_before_the_degree_sign_one_before_any_other_unit():
    assert quantities.with_unit("-1.92", "deg") == "-1.92°"
    assert quantities.with_unit("14.357", "D/(deg/s)") == "14.357 D/(°/s)"
    assert quantities.with_unit("418.8", "D/(m/s^2)") == "418.8 D/(m/s²)"
    assert quantities.with_unit("3", "") == "3"


def test_a_slope_is_in_its_points_unit_per_day():
    assert quantities.unit_text(quantities.per_day("deg")) == "°/d"
    assert quantities.unit_text(quantities.per_day("D/(m/s^2)")) == "(D/(m/s²))/d"
    assert quantities.with_unit("0.012", quantities.per_day("D/(deg/s)")) == "0.012 (D/(°/s))/d"
    assert quantities.per_day("mg") == "mg/d" and quantities.per_day("") == ""


def test_input_still_accepts_deg_and_the_stored_unit_stays_deg():
    assert quantities.own_unit("phase", "deg") == quantities.own_unit("phase", "°") == ("deg", 1.0)
    assert quantities.own_unit("angular_rate", "D/(deg/s)") == ("D/(deg/s)", 1.0)
    assert quantities.own_unit("angular_rate", "D/(°/s)") == ("D/(deg/s)", 1.0)
    assert quantities.point_unit("phase", "D/(m/s^2)") == "deg"


def test_a_matrix_group_in_words_in_the_points_order():
    """A group read back from PostgreSQL's jsonb has its keys in another order."""
    group = {"axis": "Z", "device": "IMU 1", "quantity": "angular_rate"}
    assert group_text(group) == "device IMU 1, axis Z, angular-rate sensitivity"
    assert group_text(group, "=") == "device=IMU 1, axis=Z, angular-rate sensitivity"
    assert group_text({"frequency_hz": 5.0, "quantity": "magnitude"}, "=") == "frequency_hz=5"
    assert group_text({}) == ""


def test_the_page_tags_write_the_unit_after_the_number():
    out = Template(
        "{% load labs_tags %}-1.92{% unit_after 'deg' %}|14.36{% unit_after 'D/(deg/s)' %}"
        "|U{% unit_heading 'deg' %}"
    ).render(Context())
    assert out == (
        '-1.92<span class="small text-body-secondary">°</span>'
        '|14.36 <span class="small text-body-secondary">D/(°/s)</span>'
        '|U <span class="fw-normal text-nowrap d-block small">(°)</span>'
    )


def test_a_relative_u_names_its_absolute_value_in_the_unit_as_read():
    rate = SimpleNamespace(expanded_uncertainty=0.07143, expanded_uncertainty_entered="0.5%",
                           unit="D/(deg/s)")  # fmt: skip
    absolute = SimpleNamespace(expanded_uncertainty=0.07143, unit="D/(deg/s)")
    out = Template("{% load labs_tags %}{{ a|entered_u }}|{{ b|entered_u }}").render(
        Context({"a": rate, "b": absolute})
    )
    assert out == "0.5% (0.071 D/(°/s))|0.071"


def test_the_unit_filter_writes_squares_and_degrees():
    out = Template(
        "{% load labs_tags %}{{ a|unit }}|{{ b|unit }}|{{ c|per_day|unit }}|{{ d|unit }}"
    ).render(Context({"a": "mV/(m/s^2)", "b": "D/(deg/s)", "c": "deg", "d": None}))
    assert out == "mV/(m/s²)|D/(°/s)|°/d|"


@pytest.mark.django_db
def test_the_comparison_pages_write_the_devices_unit_with_a_square(client):
    """The devices' table of the coordinator's and of a participant's comparison page: the
    nominal sensitivity and an absolute tolerance in D/(m/s²), as stored D/(m/s^2)."""
    from tests.factories import (
        ComparisonFactory,
        DeviceFactory,
        MembershipFactory,
        ParticipantFactory,
        UserFactory,
    )

    c = ComparisonFactory.create(status="open")
    DeviceFactory.create(comparison=c, unit="D/(m/s^2)", nominal_sensitivity=418.0,
                         tolerance=2.5, tolerance_relative=False)  # fmt: skip
    coordinator = UserFactory.create()
    c.coordinators.add(coordinator)
    member = UserFactory.create()
    participant = ParticipantFactory.create(comparison=c)
    MembershipFactory.create(user=member, laboratory=participant.laboratory)
    for user, url in ((coordinator, f"/coordinator/{c.code}/"),
                      (member, f"/lab/comparisons/{c.code}/")):  # fmt: skip
        client.force_login(user)
        page = client.get(url)
        assert page.status_code == 200
        html = page.content.decode()
        assert "418 D/(m/s²)" in html and "± 2.5 D/(m/s²)" in html and "m/s^2" not in html


def test_a_text_names_the_kind_by_its_label():
    assert quantities.with_kind("tangential", "angular_rate") == (
        "tangential, angular-rate sensitivity"
    )
    assert quantities.with_kind("vertical", "phase") == "vertical, sensitivity phase"
    assert quantities.with_kind("vertical", "magnitude") == "vertical"
    assert quantities.with_kind("vertical", None) == "vertical"
