"""Hostile input on the kit pages, on PostgreSQL (docs/domain.md §13, §15): hand-over notes
with control characters or 10,000 characters, times out of order, retried dispatches, and
the pilot's measurement file with NUL, huge rows, non-finite and out-of-range numbers and
dates from the ends of the calendar.  Each is refused with its exact status and a message
saying what and where, and nothing is stored half-way: the earlier state stands.

Found here: the pilot's file took 1e308, a U of 1e-320 or 1e300 (the kits page then showed
an infinite or NaN drift and the analysis run failed on it), a negative magnitude, digits
of other scripts and ``1_0`` (read as 10), and years such as 0001 and 9999 (a mistyped
year is a lever arm that decides the drift alone); a hand-over could be logged as received
before it was sent, or sent on before it arrived.
"""

from __future__ import annotations

import datetime as dt
import math
from urllib.parse import urlencode

import pytest
from django.test import Client
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from common.errors import ValidationFailed
from labs.importers.values import NUMBER_RE
from labs.kits import (
    SlotPlan,
    circulation_set,
    handover_dispatch,
    handover_receive,
    kit_create,
    kit_drift,
    kit_measurements_replace,
)
from labs.models import Handover, KitMeasurement, KitSlot, Membership
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    MeasurementPointFactory,
    ParticipantFactory,
    UserFactory,
)

pytestmark = pytest.mark.django_db

UTC = dt.UTC
HEADER = (
    "device,axis,frequency_hz,bench,direction,quantity,measured_on,sensitivity,expanded_uncertainty"
)
GOOD = ("MEMS 1,X,5,linear,vertical,,2027-01-04,418.1,0.02",
        "MEMS 1,X,5,linear,vertical,,2027-02-04,418.2,0.02")  # fmt: skip


class Round:
    """A round of one kit in a loop of two laboratories, its coordinator's and the first
    laboratory's browsers, a magnitude and a phase point of MEMS 1."""

    def __init__(self) -> None:
        self.comparison = c = ComparisonFactory.create(code="KIT-HOSTILE")
        user = UserFactory.create()
        c.coordinators.add(user)
        self.coord = Client()
        self.coord.force_login(user)
        device = DeviceFactory.create(comparison=c, name="MEMS 1")
        for quantity in ("magnitude", "phase"):
            MeasurementPointFactory.create(device=device, frequency_hz=5.0, quantity=quantity)
        self.a, self.b = (ParticipantFactory.create(comparison=c, code=code)
                          for code in ("L11", "L22"))  # fmt: skip
        self.kit = kit_create(comparison_id=c.pk, name="Kit A", serials={device: "SN-1"})
        circulation_set(kit=self.kit, plan=[
            SlotPlan(self.a, dt.date(2027, 1, 4), dt.date(2027, 1, 8)),
            SlotPlan(self.b, dt.date(2027, 1, 11), dt.date(2027, 1, 22)),
        ])  # fmt: skip
        self.first, self.second = KitSlot.objects.filter(kit=self.kit).order_by("position")
        member = UserFactory.create()
        Membership.objects.create(user=member, laboratory=self.a.laboratory, role="staff")
        self.lab = Client()
        self.lab.force_login(member)
        self.base = f"/coordinator/{c.code}/kits/{self.kit.pk}/"
        self.own = f"/lab/comparisons/{c.code}/kit/{self.first.pk}/"

    def measurements(self, *lines: str, header: str = HEADER):
        """The pasted file, posted as the page's form does (URL-encoded)."""
        body = urlencode({"measurements": "\n".join([header, *lines])})
        form = "application/x-www-form-urlencoded"
        return self.coord.post(self.base + "measurements/", body, content_type=form)

    def stored(self) -> list[tuple]:
        return list(KitMeasurement.objects.filter(kit=self.kit).order_by("measured_on")
                    .values_list("measured_on", "value", "expanded_uncertainty"))  # fmt: skip


@pytest.fixture
def kit_round(needs_postgres) -> Round:
    return Round()


def text(response) -> str:
    return response.content.decode()


# --- hand-overs --------------------------------------------------------------------------------


def test_a_condition_note_with_control_characters_is_400_and_logs_nothing(kit_round):
    r = kit_round
    assert r.coord.post(r.base + "dispatch/", {"carrier_note": "DHL 1"}).status_code == 302
    for note, code in (("pin\x00bent", "U+0000"), ("\x1b[31mbent", "U+001B"), ("a\x08", "U+0008")):
        answer = r.lab.post(r.own + "received/", {"condition": "damaged", "condition_note": note})
        assert answer.status_code == 400
        assert f"condition_note: The value contains the control character {code}" in text(answer)
        assert Handover.objects.get(to_slot=r.first).received_at is None
    answer = r.lab.post(
        r.own + "received/", {"condition": "damaged", "condition_note": "a\tb\r\nc"}
    )
    assert answer.status_code == 302  # tab and line breaks are text
    assert Handover.objects.get(to_slot=r.first).condition_note == "a\tb\r\nc"


def test_notes_of_10000_characters_are_400_naming_the_limit_and_store_nothing(kit_round):
    r = kit_round
    long = "x" * 10_000
    answer = r.coord.post(r.base + "dispatch/", {"carrier_note": long})
    assert answer.status_code == 400
    assert "The carrier note is longer than 500 characters." in text(answer)
    assert not Handover.objects.exists()
    assert r.coord.post(r.base + "dispatch/", {"carrier_note": "DHL 1"}).status_code == 302
    answer = r.lab.post(r.own + "received/", {"condition": "damaged", "condition_note": long})
    assert answer.status_code == 400
    assert "at most 1000 characters (it has 10000)" in text(answer)
    assert Handover.objects.get(to_slot=r.first).received_at is None
    # the provider's receipt of the returned kit: the service's own limit
    handover_receive(handover=Handover.objects.get(to_slot=r.first), user=None, condition="good")
    handover_dispatch(kit=r.kit, from_slot=r.first, user=None)
    handover_receive(handover=Handover.objects.get(to_slot=r.second), user=None, condition="good")
    back = handover_dispatch(kit=r.kit, from_slot=r.second, user=None)
    answer = r.coord.post(r.base + "returned/", {"condition": "damaged", "condition_note": long})
    assert answer.status_code == 400
    assert "The condition note is longer than 1000 characters." in text(answer)
    back.refresh_from_db()
    assert (back.received_at, back.condition, back.condition_note) == (None, "", "")
    assert r.coord.post(r.base + "returned/", {"condition": "good"}).status_code == 302


def test_a_kit_is_not_received_before_it_was_sent_nor_sent_on_before_it_arrived(kit_round):
    r = kit_round
    sent = handover_dispatch(kit=r.kit, from_slot=None, user=None,
                             at=dt.datetime(2027, 1, 2, 12, tzinfo=UTC))  # fmt: skip
    with pytest.raises(ValidationFailed) as caught:
        handover_receive(handover=sent, user=None, condition="good",
                         at=dt.datetime(2027, 1, 2, 11, 59, tzinfo=UTC))  # fmt: skip
    assert caught.value.status_code == 400
    assert caught.value.message == (
        "The kit cannot be received at 2027-01-02 11:59 UTC, before it was sent "
        "(2027-01-02 12:00 UTC)."
    )
    assert Handover.objects.get(pk=sent.pk).received_at is None
    arrived = dt.datetime(2027, 1, 2, 12, tzinfo=UTC)  # the same instant is not before
    handover_receive(handover=sent, user=None, condition="good", at=arrived)
    with pytest.raises(ValidationFailed, match=r"cannot be sent on at 2027-01-01 .* before its"):
        handover_dispatch(kit=r.kit, from_slot=r.first, user=None,
                          at=dt.datetime(2027, 1, 1, tzinfo=UTC))  # fmt: skip
    assert not Handover.objects.filter(from_slot=r.first).exists()
    # and an arrival logged on the page now, after a dispatch dated in the future, is refused
    later = handover_dispatch(kit=r.kit, from_slot=r.first, user=None,
                              at=dt.datetime(2999, 1, 1, tzinfo=UTC))  # fmt: skip
    member = UserFactory.create()
    Membership.objects.create(user=member, laboratory=r.b.laboratory, role="staff")
    lab_b = Client()
    lab_b.force_login(member)
    url = f"/lab/comparisons/{r.comparison.code}/kit/{r.second.pk}/received/"
    answer = lab_b.post(url, {"condition": "good"})
    assert answer.status_code == 400 and "before it was sent (2999-01-01 00:00 UTC)" in text(answer)
    assert Handover.objects.get(pk=later.pk).received_at is None


def test_a_retried_dispatch_answers_the_first_one(kit_round):
    r = kit_round
    for _ in range(2):
        assert r.coord.post(r.base + "dispatch/", {"carrier_note": "DHL 1"}).status_code == 302
    assert r.lab.post(r.own + "received/", {"condition": "good"}).status_code == 302
    for note in ("UPS 7", "UPS 7", "another note"):  # a retry, and a late second click
        assert r.lab.post(r.own + "dispatched/", {"carrier_note": note}).status_code == 302
    assert list(Handover.objects.filter(kit=r.kit).order_by("pk")
                .values_list("from_slot", "to_slot", "carrier_note")) == [
        (None, r.first.pk, "DHL 1"), (r.first.pk, r.second.pk, "UPS 7")]  # fmt: skip


# --- the pilot's measurements ------------------------------------------------------------------


def test_a_nul_in_the_pilots_file_is_400_and_the_earlier_file_stands(kit_round):
    r = kit_round
    assert r.measurements(*GOOD).status_code == 302
    before = r.stored()
    answer = r.measurements(GOOD[0].replace("418.1", "418\x00.1"))
    assert answer.status_code == 400
    assert "measurements: The value contains the control character U+0000" in text(answer)
    assert r.stored() == before and len(before) == 2


@pytest.mark.parametrize(
    ("cell", "value", "message"),
    [
        ("sensitivity", "nan", "sensitivity must be finite and &gt; 0"),
        ("sensitivity", "inf", "sensitivity must be finite and &gt; 0"),
        ("sensitivity", "1e400", "sensitivity must be finite and &gt; 0"),
        ("sensitivity", "1e308", "sensitivity must be between 1e-30 and 1e30, got 1e308"),
        ("sensitivity", "-418.1", "sensitivity must be finite and &gt; 0"),
        ("sensitivity", "١٢", "sensitivity must be a number in ASCII digits, got &#x27;١٢&#x27;"),
        ("sensitivity", "1_0", "sensitivity must be a number in ASCII digits, got &#x27;1_0&#x27;"),
        ("expanded_uncertainty", "1e-320", "expanded_uncertainty must be between 1e-30 and 1e30, "
                                           "got 1e-320"),
        ("expanded_uncertainty", "1e300", "expanded_uncertainty must be between 1e-30 and 1e30"),
        ("expanded_uncertainty", "0", "expanded_uncertainty must be finite and &gt; 0"),
        ("measured_on", "9999-12-31", "measured_on 9999-12-31 is more than 10 years from the "
                                      "round"),
        ("measured_on", "0001-01-01", "measured_on 0001-01-01 is more than 10 years from the "
                                      "round"),
        ("measured_on", "2027-02-30", "measured_on must be a date YYYY-MM-DD"),
        ("frequency_hz", "inf", "frequency_hz must be finite and &gt; 0"),
    ],
)  # fmt: skip
def test_bad_pilot_cells_are_400_naming_the_line_and_the_earlier_file_stands(
    kit_round, cell, value, message
):
    r = kit_round
    assert r.measurements(*GOOD).status_code == 302
    before = r.stored()
    index = HEADER.split(",").index(cell)
    bad = GOOD[1].split(",")
    bad[index] = value
    answer = r.measurements(GOOD[0], ",".join(bad))
    assert answer.status_code == 400
    assert "The measurements of Kit A have errors." in text(answer)
    assert f"line 3: {message}" in text(answer), text(answer)[-3000:]
    assert r.stored() == before
    assert r.coord.get(f"/coordinator/{r.comparison.code}/kits/").status_code == 200


def test_huge_pilot_files_are_refused_whole(kit_round, settings):
    r = kit_round
    assert r.measurements(*GOOD).status_code == 302
    before = r.stored()
    for lines, status, message in (
        ([GOOD[0].replace("418.1", "9" * 200_000)], 400, "not a readable CSV"),
        ([GOOD[0] + "," * 1_000_000], 400, "line 2: more fields than the header names"),
        ([GOOD[0]] * 100_001, 400, "At most 100000 measurements per kit."),
        (["x" * 10_000_001], 400, "Paste at most 10 MB of measurements."),
    ):
        answer = r.measurements(*lines)
        assert answer.status_code == status and message in text(answer), message
        assert r.stored() == before
    settings.DATA_UPLOAD_MAX_MEMORY_SIZE = 1_000_000  # refused on its declared size, unread
    answer = r.measurements(*[GOOD[0]] * 30_000)
    assert answer.status_code == 413 and "the limit is" in text(answer)
    assert r.stored() == before


def test_a_pilots_phases_are_stored_as_their_exact_wrap(kit_round):
    r = kit_round
    lines = [f"MEMS 1,X,5,linear,vertical,phase,2027-01-{d:02d},{v},0.5"
             for d, v in ((4, "540"), (5, "-180"), (6, "0.1"), (7, "1e22"), (8, "-0"))]  # fmt: skip
    assert r.measurements(*lines).status_code == 302
    assert [v for _, v, _ in r.stored()] == [180.0, 180.0, 0.1, -80.0, 0.0]
    answer = r.measurements(lines[0].replace("540", "-1e31"))
    assert answer.status_code == 400 and "line 2: sensitivity must be 0 or of a size" in text(
        answer
    )


def _hostile(cell: str) -> bool:
    """Not a magnitude the file takes, and not a cell that changes the file's shape."""
    if any(c in cell for c in ',"\r\n'):
        return False
    plain = cell.strip()
    return not (NUMBER_RE.fullmatch(plain) and 1e-30 <= float(plain) <= 1e30)


_PILOT_CELLS = st.one_of(
    st.floats().map(repr),
    st.text(alphabet=st.characters(codec="utf-8"), max_size=8),
).filter(_hostile)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(_PILOT_CELLS, st.floats(min_value=1e-30, max_value=1e30))
def test_a_pilot_magnitude_is_stored_exactly_or_its_line_is_named(kit_round, hostile, good):
    """Negative and positive generation on one file: a line with a hostile magnitude is
    named (line 3) and nothing of the file is stored; a magnitude in range is stored to
    the last bit, and the kit's drift is finite."""
    r = kit_round
    first = GOOD[0].replace("418.1", repr(good))
    kit_measurements_replace(kit=r.kit, text="\n".join([HEADER, first, GOOD[1]]))
    stored = r.stored()
    assert stored[0][1] == good
    rows, _ = kit_drift(r.kit)
    assert all(math.isfinite(x) for row in rows for x in (row.value, row.u_value))
    with pytest.raises(ValidationFailed) as caught:
        kit_measurements_replace(
            kit=r.kit, text="\n".join([HEADER, first, GOOD[1].replace("418.2", hostile)])
        )
    assert [e["row"] for e in caught.value.errors] == [3], (hostile, caught.value.errors)
    assert r.stored() == stored
