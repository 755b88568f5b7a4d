"""The kit pages (docs/domain.md §15) persona by persona: the coordinator creates a kit,
plans its loop (a bad plan named line by line) and sends it out; each laboratory logs the
arrival and the dispatch of its own slot only and never sees who holds the kit before or
after it; another laboratory's slot and another round's coordinator get 404."""

from __future__ import annotations

from django.core.files.uploadedfile import SimpleUploadedFile
from django.test import Client

from labs.models import Handover, KitSlot, Membership
from proficiency.models import Kit
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    ParticipantFactory,
    UserFactory,
)

PNG = b"\x89PNG\r\n\x1a\n" + b"\x00" * 64


def _member(participant):
    user = UserFactory.create()
    Membership.objects.create(user=user, laboratory=participant.laboratory, role="staff")
    client = Client()
    client.force_login(user)
    return client


def _world(db):
    c = ComparisonFactory.create()
    coordinator = UserFactory.create()
    c.coordinators.add(coordinator)
    devices = [DeviceFactory.create(comparison=c, name=f"MEMS {i}") for i in (1, 2)]
    alpha, beta = (
        LaboratoryFactory.create(name="Alpha Lab"),
        LaboratoryFactory.create(name="Beta Lab"),
    )
    a = ParticipantFactory.create(comparison=c, code="L11", laboratory=alpha)
    b = ParticipantFactory.create(comparison=c, code="L22", laboratory=beta)
    coord = Client()
    coord.force_login(coordinator)
    return c, devices, a, b, coord


def test_a_round_of_one_kit_as_the_coordinator_and_two_labs_run_it(db):
    c, devices, a, b, coord = _world(db)
    base = f"/coordinator/{c.code}/kits/"
    assert coord.get(base).status_code == 200
    r = coord.post(base + "new/", {"name": "Kit A", f"serial_{devices[0].pk}": "SN-1",
                                   f"serial_{devices[1].pk}": "SN-2"})  # fmt: skip
    assert r.status_code == 302
    kit = Kit.objects.get(comparison=c, name="Kit A")
    bad = coord.post(
        f"{base}{kit.pk}/plan/", {"plan": "L11, 2027-01-04, 2027-01-08\nL99, 2027-01-11, x"}
    )
    assert bad.status_code == 400
    assert "line 2: no participant &#x27;L99&#x27; in this round" in bad.content.decode()
    plan = "L11, 2027-01-04, 2027-01-08\nL22, 2027-01-11, 2027-01-22"
    assert coord.post(f"{base}{kit.pk}/plan/", {"plan": plan}).status_code == 302
    first, second = KitSlot.objects.filter(kit=kit).order_by("position")
    assert coord.post(f"{base}{kit.pk}/dispatch/", {"carrier_note": "DHL 1"}).status_code == 302

    lab_a, lab_b = _member(a), _member(b)
    page = lab_a.get(f"/lab/comparisons/{c.code}/kit/").content.decode()
    assert "SN-1" in page and "Log arrival" in page and "DHL 1" in page
    assert "L22" not in page and "Beta Lab" not in page  # the next holder is not shown
    # lab B cannot log lab A's arrival or dispatch: 404, nothing stored
    assert lab_b.post(f"/lab/comparisons/{c.code}/kit/{first.pk}/received/",
                      {"condition": "good"}).status_code == 404  # fmt: skip
    assert Handover.objects.get(to_slot=first).received_at is None
    # a photo that is not an image is refused on the form
    r = lab_a.post(f"/lab/comparisons/{c.code}/kit/{first.pk}/received/",
                   {"condition": "damaged", "condition_note": "dent",
                    "photo": SimpleUploadedFile("p.png", b"GIF89a....")})  # fmt: skip
    assert r.status_code == 400 and "JPEG or PNG" in r.content.decode()
    r = lab_a.post(f"/lab/comparisons/{c.code}/kit/{first.pk}/received/",
                   {"condition": "damaged", "condition_note": "dent on MEMS 2",
                    "photo": SimpleUploadedFile("p.png", PNG)})  # fmt: skip
    assert r.status_code == 302
    arrival = Handover.objects.get(to_slot=first)
    assert (arrival.condition, arrival.condition_note) == ("damaged", "dent on MEMS 2")
    assert arrival.photo.read() == PNG
    assert lab_a.post(f"/lab/comparisons/{c.code}/kit/{first.pk}/dispatched/",
                      {"carrier_note": "UPS 7"}).status_code == 302  # fmt: skip
    assert Handover.objects.get(from_slot=first).to_slot == second
    # the coordinator sees the damage; lab B now has the kit to log
    board = coord.get(base).content.decode()
    assert "dent on MEMS 2" in board and "damaged</span>" in board
    assert "Log arrival" in lab_b.get(f"/lab/comparisons/{c.code}/kit/").content.decode()


def test_the_kit_page_without_a_kit_and_another_rounds_coordinator(db):
    c, _, a, _, _ = _world(db)
    page = _member(a).get(f"/lab/comparisons/{c.code}/kit/")
    assert page.status_code == 200 and "No kit is planned for you" in page.content.decode()
    stranger = UserFactory.create()
    ComparisonFactory.create().coordinators.add(stranger)
    other = Client()
    other.force_login(stranger)
    assert other.get(f"/coordinator/{c.code}/kits/").status_code == 404
    assert other.post(f"/coordinator/{c.code}/kits/new/", {"name": "X"}).status_code == 404
    assert not Kit.objects.exists()


def test_the_coordinator_stores_the_pilots_repeats_and_reads_the_drift(db):
    from tests.factories import MeasurementPointFactory

    c, devices, _, _, coord = _world(db)
    MeasurementPointFactory.create(device=devices[0], frequency_hz=5.0)
    base = f"/coordinator/{c.code}/kits/"
    coord.post(base + "new/", {"name": "Kit A", f"serial_{devices[0].pk}": "SN-1"})
    kit = Kit.objects.get(comparison=c)
    header = "device,axis,frequency_hz,bench,direction,measured_on,sensitivity,expanded_uncertainty"
    wrong = header + "\nMEMS 9,X,5,linear,vertical,2027-01-04,1,0.1"
    bad = coord.post(f"{base}{kit.pk}/measurements/", {"measurements": wrong})
    assert bad.status_code == 400
    assert (
        "line 2: MEMS 9, X, 5 Hz, linear vertical is not a measurement point"
        in bad.content.decode()
    )
    days = ("2027-01-04", "2027-02-01", "2027-03-01", "2027-03-29")
    lines = [f"MEMS 1,X,5,linear,vertical,{d},{418 + 0.5 * i},0.02" for i, d in enumerate(days)]
    r = coord.post(f"{base}{kit.pk}/measurements/", {"measurements": "\n".join([header, *lines])})
    assert r.status_code == 302
    page = coord.get(base).content.decode()
    assert "drifting</span>" in page and "4 Jan 2027 – 29 Mar 2027" in page


def test_the_pilots_file_help_names_the_quantity_column(db):
    """A round of phases or angular rates needs the optional ``quantity`` column of the
    pilot's file (docs/domain.md §15): the kits page's help says so."""
    c, devices, _, _, coord = _world(db)
    coord.post(f"/coordinator/{c.code}/kits/new/", {"name": "Kit A",
                                                    f"serial_{devices[0].pk}": "SN-1"})  # fmt: skip
    page = coord.get(f"/coordinator/{c.code}/kits/").content.decode()
    assert "<code>quantity</code> optional (magnitude, phase or angular_rate" in page


def test_the_comparison_pages_name_each_points_quantity(db):
    """A magnitude and a phase at the same device, axis, frequency and bench are two
    measurands: the lab's and the coordinator's lists of points tell them apart."""
    from tests.factories import MeasurementPointFactory

    c, devices, a, _b, coord = _world(db)
    for quantity in ("magnitude", "phase", "angular_rate"):
        MeasurementPointFactory.create(device=devices[0], frequency_hz=10.0, quantity=quantity)
    for page in (_member(a).get(f"/lab/comparisons/{c.code}/"),
                 coord.get(f"/coordinator/{c.code}/")):  # fmt: skip
        assert page.status_code == 200
        html = page.content.decode()
        for label in ("sensitivity magnitude", "sensitivity phase", "angular-rate sensitivity"):
            assert f"<td>{label}</td>" in html, label
