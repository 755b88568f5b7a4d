"""A kit's measurements with the optional lab column (docs/domain.md §14, §15): blank is
the pilot's repeat, a code is that linking laboratory's measurement of the kit, refused
line by line unless the laboratory holds a slot on the kit, and nothing stored unless every
line is good; the drift is judged on the pilot's repeats only, a phase's unwrapped."""

from __future__ import annotations

import numpy as np
import pytest
from django.db import IntegrityError, transaction

from common.errors import ValidationFailed
from labs.kits import kit_drift, kit_linking_counts, kit_measurements_replace
from labs.models import KitMeasurement
from tests.factories import MeasurementPointFactory, ParticipantFactory
from tests.labs.test_kits import HEADER, round_  # noqa: F401 (the fixture)

LAB_HEADER = HEADER.replace("expanded_uncertainty", "expanded_uncertainty,lab")
DAYS = ("2027-01-04", "2027-02-01", "2027-03-01", "2027-03-29")


def _pilot_lines(value: float = 418.0) -> list[str]:
    return [f"MEMS 1,X,5,linear,vertical,{d},{value + 0.001 * i},0.02," for i, d in enumerate(DAYS)]


def test_a_lab_column_names_the_linking_laboratory_with_its_full_u(round_):  # noqa: F811
    _, kit, _, labs, devices = round_
    point = MeasurementPointFactory.create(device=devices[0], frequency_hz=5.0)
    lines = [*_pilot_lines(), f"MEMS 1,X,5,linear,vertical,2027-01-20,418.4,3.0,{labs[0].code}"]
    assert kit_measurements_replace(kit=kit, text=LAB_HEADER + "\n".join(lines)) == 5
    rows = KitMeasurement.objects.filter(kit=kit, measurement_point=point)
    assert sorted(rows.values_list("participant__code", "value", "expanded_uncertainty"),
                  key=str) == sorted([(None, 418.0 + 0.001 * i, 0.02) for i in range(4)]
                                     + [(labs[0].code, 418.4, 3.0)], key=str)  # fmt: skip
    assert kit_linking_counts(kit) == [(labs[0].code, 1)]
    drift, notes = kit_drift(kit)  # the laboratory's line is no repeat of the pilot
    assert notes == [] and [r.n for r in drift] == [4]
    assert drift[0].value == pytest.approx(np.mean([418.0 + 0.001 * i for i in range(4)]))


def test_an_unknown_code_or_a_lab_off_the_kit_is_refused_by_line_and_nothing_stored(
    round_,  # noqa: F811
):
    c, kit, _, labs, devices = round_
    MeasurementPointFactory.create(device=devices[0], frequency_hz=5.0)
    kit_measurements_replace(kit=kit, text=LAB_HEADER + "\n".join(_pilot_lines()))
    before = sorted(KitMeasurement.objects.values_list("pk", flat=True))
    # in the round, not the loop; three digits, which the factory's codes never have
    stranger = ParticipantFactory.create(comparison=c, code="L777")
    ParticipantFactory.create(code="L888")  # another round's
    lines = [
        *_pilot_lines(419.0),
        f"MEMS 1,X,5,linear,vertical,2027-01-20,418.4,3.0,{labs[0].code}",
        "MEMS 1,X,5,linear,vertical,2027-01-20,418.4,3.0,L999",
        f"MEMS 1,X,5,linear,vertical,2027-01-20,418.4,3.0,{stranger.code}",
        "MEMS 1,X,5,linear,vertical,2027-01-20,418.4,3.0,L888",
        f"MEMS 1,X,5,linear,vertical,2027-01-20,418.5,3.0,{labs[0].code}",
    ]
    with pytest.raises(ValidationFailed) as caught:
        kit_measurements_replace(kit=kit, text=LAB_HEADER + "\n".join(lines))
    assert caught.value.message == "The measurements of Kit A have errors."
    assert [(e["row"], e["message"]) for e in caught.value.errors] == [
        (7, "lab: no participant 'L999' in this round"),
        (8, "lab: L777 holds no slot on Kit A, so it cannot have measured it (only the "
            "laboratories of its loop do)"),
        (9, "lab: no participant 'L888' in this round"),
        (10, "a second measurement of this point that day by this lab"),
    ]  # fmt: skip
    # the earlier file stands, row for row: the good lines of the bad file are not stored
    assert sorted(KitMeasurement.objects.values_list("pk", flat=True)) == before
    assert set(KitMeasurement.objects.values_list("value", flat=True)) == {
        418.0 + 0.001 * i for i in range(4)
    }


def test_one_repeat_per_point_and_day_and_one_per_lab_beside_it(round_):  # noqa: F811
    """The constraints: the pilot's repeat once a day, a laboratory's beside it once."""
    _, kit, _, labs, devices = round_
    point = MeasurementPointFactory.create(device=devices[0], frequency_hz=5.0)
    day = "2027-01-04"
    KitMeasurement.objects.create(kit=kit, measurement_point=point, measured_on=day, value=1,
                                  expanded_uncertainty=1)  # fmt: skip
    KitMeasurement.objects.create(kit=kit, measurement_point=point, measured_on=day, value=1,
                                  expanded_uncertainty=1, participant=labs[0])  # fmt: skip
    for who in (None, labs[0]):
        with pytest.raises(IntegrityError), transaction.atomic():
            KitMeasurement.objects.create(kit=kit, measurement_point=point, measured_on=day,
                                          value=2, expanded_uncertainty=1,
                                          participant=who)  # fmt: skip
    assert KitMeasurement.objects.count() == 2


def test_a_phase_series_crossing_180_is_judged_on_its_unwrapped_values(round_):  # noqa: F811
    _, kit, _, _, devices = round_
    MeasurementPointFactory.create(device=devices[0], frequency_hz=5.0, quantity="phase")
    raw = [179.0, 179.9, -179.2, -178.3]  # 179, 179.9, 180.8, 181.7 on the line
    header = HEADER.replace("expanded_uncertainty", "expanded_uncertainty,quantity")
    lines = [f"MEMS 1,X,5,linear,vertical,{d},{v},0.08,phase"
             for d, v in zip(DAYS, raw, strict=True)]  # fmt: skip
    kit_measurements_replace(kit=kit, text=header + "\n".join(lines))
    (row,), _ = kit_drift(kit)
    t = np.array([0.0, 28.0, 56.0, 84.0])
    slope, at_mean = np.polyfit(t - t.mean(), np.unwrap(raw, period=360), 1)
    assert row.model == "linear"
    assert row.slope_per_day == pytest.approx(slope, rel=1e-10)
    assert row.value == pytest.approx(at_mean - 360.0, rel=1e-12)  # 180.35° wrapped: −179.65°


def test_the_coordinators_page_stores_a_linking_lab_and_names_a_bad_line(db):
    from proficiency.models import Kit
    from tests.labs.test_kit_pages import _world

    c, devices, _, _, coord = _world(db)
    MeasurementPointFactory.create(device=devices[0], frequency_hz=5.0)
    base = f"/coordinator/{c.code}/kits/"
    coord.post(base + "new/", {"name": "Kit A", f"serial_{devices[0].pk}": "SN-1"})
    kit = Kit.objects.get(comparison=c)
    plan = "L11, 2027-01-04, 2027-01-08\nL22, 2027-01-11, 2027-01-22"
    assert coord.post(f"{base}{kit.pk}/plan/", {"plan": plan}).status_code == 302
    header = LAB_HEADER.strip()
    good = "MEMS 1,X,5,linear,vertical,2027-01-04,418.0,0.02,"
    bad = coord.post(f"{base}{kit.pk}/measurements/", {"measurements": "\n".join([
        header, good, "MEMS 1,X,5,linear,vertical,2027-01-05,418.2,3,L33"])})  # fmt: skip
    assert bad.status_code == 400
    assert "line 3: lab: no participant &#x27;L33&#x27; in this round" in bad.content.decode()
    assert not KitMeasurement.objects.exists()
    r = coord.post(f"{base}{kit.pk}/measurements/", {"measurements": "\n".join([
        header, good, "MEMS 1,X,5,linear,vertical,2027-01-15,418.2,3,L22"])})  # fmt: skip
    assert r.status_code == 302
    assert list(KitMeasurement.objects.order_by("measured_on").values_list(
        "participant__code", "expanded_uncertainty")) == [(None, 0.02), ("L22", 3.0)]  # fmt: skip
    page = coord.get(base).content.decode()
    assert "Measured too by the laboratories linking it to their other loop: L22 (1)" in page
