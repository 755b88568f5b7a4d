"""The demo comparison has one lab with a raw linear and a raw curvilinear record."""

import pytest
from django.core.management import call_command

from coordination.demo import RAW_BIAS, RAW_DATA_LAB
from labs.models import RawFile, RawRecomputation, RawRecord

pytestmark = pytest.mark.django_db


def test_demo_raw_records_recomputed_and_idempotent(django_capture_on_commit_callbacks):
    with django_capture_on_commit_callbacks(execute=True):
        call_command("load_demo", password="pw-demo-1", stdout=None)
    first = (RawFile.objects.count(), RawRecord.objects.count(), RawRecomputation.objects.count())
    assert first == (3, 2, 2)  # linear int16, curvilinear int16, encoder CSV
    for row in RawRecomputation.objects.select_related("record__participant__laboratory"):
        assert row.record.participant.laboratory.name == RAW_DATA_LAB
        assert row.status == "succeeded", row.error
        truth = row.reported_value * RAW_BIAS
        assert row.sensitivity == pytest.approx(truth, rel=5e-4)
        assert row.sensitivity is not None and row.expanded_uncertainty is not None
        assert row.en == pytest.approx(
            (row.reported_value - row.sensitivity)
            / (row.reported_expanded_uncertainty**2 + row.expanded_uncertainty**2) ** 0.5
        )
    assert {r.measurement_point.bench for r in RawRecord.objects.all()} == {
        "linear", "curvilinear",
    }  # fmt: skip
    with django_capture_on_commit_callbacks(execute=True):
        call_command("load_demo", stdout=None)
    again = (RawFile.objects.count(), RawRecord.objects.count(), RawRecomputation.objects.count())
    assert again == first
