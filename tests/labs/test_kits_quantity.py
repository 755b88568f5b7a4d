"""The pilot's kit file with the optional quantity column (docs/domain.md §12, §15): a
phase is its point's own measurement, stored wrapped; a bad kind is named by its line."""

import pytest

from common.errors import ValidationFailed
from labs.kits import kit_measurements_replace
from labs.models import KitMeasurement
from tests.factories import MeasurementPointFactory
from tests.labs.test_kits import HEADER, round_  # noqa: F401 (the fixture)


def test_a_phase_and_a_magnitude_of_one_point(round_):  # noqa: F811
    c, kit, _, _, devices = round_
    points = {
        q: MeasurementPointFactory.create(comparison=c, device=devices[0], quantity=q)
        for q in ("magnitude", "phase")
    }
    header = HEADER.replace("expanded_uncertainty", "expanded_uncertainty,quantity")
    text = header + "\n".join([
        "MEMS 1,X,10,linear,vertical,2027-01-04,418.1,0.02,",
        "MEMS 1,X,10,linear,vertical,2027-01-04,190.5,0.5,phase",
    ])  # fmt: skip
    assert kit_measurements_replace(kit=kit, text=text) == 2
    stored = dict(KitMeasurement.objects.values_list("measurement_point_id", "value"))
    assert stored == {points["magnitude"].pk: 418.1, points["phase"].pk: -169.5}
    bad = header + "MEMS 1,X,10,linear,vertical,2027-01-05,1,0.5,phasor"
    with pytest.raises(ValidationFailed) as caught:
        kit_measurements_replace(kit=kit, text=bad)
    assert [(e["row"], e["message"]) for e in caught.value.errors] == [
        (2, "quantity must be one of magnitude, phase, angular_rate, got 'phasor'")
    ]
    assert KitMeasurement.objects.count() == 2  # the earlier file stays
