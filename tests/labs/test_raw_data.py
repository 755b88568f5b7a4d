"""Raw records on the web: upload page, per-record page, coordinator review, the task."""

from __future__ import annotations

import os
import re

import numpy as np
import pytest
from django.core.files.uploadedfile import SimpleUploadedFile

from analysis.core.signals.sinefit import fit_known_frequency
from common.errors import ValidationFailed
from labs.models import Participant, RawFile, RawRecomputation, RawRecord
from labs.raw import PLOT_HARMONICS, _model
from labs.raw_services import en_number, raw_recompute_execute, raw_upload_submit
from proficiency.models import MeasurementPoint
from tests.factories import (
    ComparisonFactory,
    LaboratoryFactory,
    MembershipFactory,
    UserFactory,
)
from tests.labs.raw_data_helpers import (
    TRUTH,
    int16_bytes,
    linear,
    raw_round,
    reporting,
    sidecar,
    staff,
    upload_fields,
)

pytestmark = pytest.mark.django_db
CODE = "RAW-WEB"
REPORTED, REPORTED_U = 420.0, 8.0


@pytest.fixture
def world():
    lab_a, lab_b = (
        LaboratoryFactory.create(name="Alpha Secret Lab"),
        LaboratoryFactory.create(name="Bravo"),
    )
    users = {
        "a": staff(lab_a),
        "b": MembershipFactory.create(laboratory=lab_b).user,
        "coord": UserFactory.create(username="coord-web"),
        "coord2": UserFactory.create(username="coord-other"),
    }
    grid = {"axes": ["X"], "frequencies_hz": [10], "benches": ["linear"]}
    comparison, points = raw_round(CODE, "MEMS 1", grid)
    comparison.coordinators.add(users["coord"])
    ComparisonFactory.create(code="OTHER").coordinators.add(users["coord2"])
    for lab, code in ((lab_a, "W11"), (lab_b, "W22")):
        reporting(comparison, lab, code, points, (REPORTED, REPORTED_U))
    return users


def upload(client, record, **extra):
    point = MeasurementPoint.objects.get(comparison__code=CODE)
    data = {"point": point.pk, **upload_fields(record, name="run1.bin"), **extra}
    return client.post(f"/lab/comparisons/{CODE}/raw-data/", data)


def test_upload_page_recomputes_and_shows_the_truth(
    client, world, django_capture_on_commit_callbacks
):
    client.force_login(world["a"])
    with django_capture_on_commit_callbacks(execute=True):
        response = upload(client, linear())
    record = RawRecord.objects.get()
    assert response.status_code == 302
    assert response["Location"] == f"/lab/comparisons/{CODE}/raw-data/{record.pk}/"
    row = record.recomputation
    assert row.sensitivity == pytest.approx(TRUTH[0], rel=5e-4)
    page = client.get(response["Location"]).content.decode()
    shown = re.search(r'data-testid="recomputed">([^<]+)<', page)
    en_shown = re.search(r'data-testid="en">([-0-9.]+)', page)
    fs_shown = re.search(r'data-testid="fs">([0-9.]+)', page)
    assert shown and en_shown and fs_shown, page
    assert float(shown.group(1)) == pytest.approx(TRUTH[0], rel=5e-4)
    assert row.sensitivity is not None and row.expanded_uncertainty is not None
    en = (REPORTED - row.sensitivity) / np.hypot(REPORTED_U, row.expanded_uncertainty)
    assert float(en_shown.group(1)) == pytest.approx(en, abs=5e-4)
    assert float(fs_shown.group(1)) == pytest.approx(1663.7, abs=0.01)
    assert "<svg" in page and "fitted sine" in page
    listing = client.get(f"/lab/comparisons/{CODE}/raw-data/").content.decode()
    assert "run1.bin" in listing


def test_web_bad_file_shows_the_readers_message(client, world):
    client.force_login(world["a"])
    record = linear(duration=2.0)
    point = MeasurementPoint.objects.get(comparison__code=CODE)
    response = client.post(
        f"/lab/comparisons/{CODE}/raw-data/",
        {"point": point.pk, "file": SimpleUploadedFile("run1.bin", int16_bytes(record)[:-2]),
         "sidecar": SimpleUploadedFile("run1.bin.json", sidecar(record))},
    )  # fmt: skip
    assert response.status_code == 200
    assert "truncated file" in response.content.decode()
    assert RawRecord.objects.count() == 0


def test_web_oversize_is_413_with_nothing_stored(client, world, settings):
    settings.RAW_UPLOAD_MAX_BYTES = 5_000
    client.force_login(world["a"])
    response = upload(client, linear(duration=2.0))
    assert response.status_code == 413
    assert "limit" in response.content.decode()
    assert (RawFile.objects.count(), RawRecord.objects.count()) == (0, 0)


def test_other_lab_404_and_coordinator_review(client, world, django_capture_on_commit_callbacks):
    client.force_login(world["a"])
    with django_capture_on_commit_callbacks(execute=True):
        upload(client, linear(duration=5.0))
    pk = RawRecord.objects.get().pk
    url = f"/lab/comparisons/{CODE}/raw-data/{pk}/"
    client.force_login(world["b"])
    assert client.get(url).status_code == 404
    assert "run1.bin" not in client.get(f"/lab/comparisons/{CODE}/raw-data/").content.decode()
    client.logout()
    assert client.get(url).status_code == 302  # to the login page
    client.force_login(world["coord"])
    review = client.get(f"/coordinator/{CODE}/raw-data/")
    assert review.status_code == 200
    page = review.content.decode()
    assert "W11" in page and "Alpha Secret Lab" not in page and "<svg" in page
    assert 'data-testid="recomputed"' in page
    client.force_login(world["coord2"])
    assert client.get(f"/coordinator/{CODE}/raw-data/").status_code == 404


def test_task_twice_is_one_result(client, world, django_capture_on_commit_callbacks):
    client.force_login(world["a"])
    with django_capture_on_commit_callbacks(execute=False):  # the task is not run yet
        upload(client, linear(duration=5.0))
    record = RawRecord.objects.get()
    assert record.recomputation.status == "pending"
    assert raw_recompute_execute(record_id=record.pk) == "succeeded"
    first = RawRecomputation.objects.get()
    assert raw_recompute_execute(record_id=record.pk) == "succeeded"
    assert RawRecomputation.objects.count() == 1
    assert RawRecomputation.objects.get().finished_at == first.finished_at


def test_en_number_by_hand():
    assert en_number(420.0, 8.0, 421.0, 6.0) == pytest.approx(-1.0 / 10.0)


def test_plotted_model_matches_a_clean_record():
    """The figure's fitted curve uses the fit's own phase convention."""
    n, nu = 700, 10.0 / 1663.7
    k = np.arange(n) - (n - 1) / 2
    y = 3.0 + 100 * np.cos(2 * np.pi * nu * k + 0.7) + 5 * np.cos(4 * np.pi * nu * k - 0.2)
    fit = fit_known_frequency(y, nu, PLOT_HARMONICS)
    model = _model(fit.amplitude[0], fit.phase[0], float(fit.offset[0]), nu, n)
    assert np.max(np.abs(model - y)) < 1e-8


def test_web_declared_oversize_is_refused_before_reading(client, world, settings):
    settings.RAW_UPLOAD_MAX_BYTES = 1_000
    client.force_login(world["a"])
    response = client.post(
        f"/lab/comparisons/{CODE}/raw-data/",
        b"--b--",
        content_type="multipart/form-data; boundary=b",
        CONTENT_LENGTH="99999999",
    )
    assert response.status_code == 413
    assert RawRecord.objects.count() == 0


def test_file_store_dedups_and_restores_a_lost_file():
    from labs.raw_services import raw_file_store

    first = raw_file_store(b"\x01\x00\x02\x00")
    assert raw_file_store(b"\x01\x00\x02\x00").pk == first.pk
    assert RawFile.objects.count() == 1
    path = first.file.path
    assert os.stat(path).st_mode & 0o777 == 0o440  # never modified in place
    os.chmod(path, 0o600)
    os.remove(path)
    again = raw_file_store(b"\x01\x00\x02\x00")
    assert again.pk == first.pk
    with open(path, "rb") as fh:
        assert fh.read() == b"\x01\x00\x02\x00"


def test_a_recomputation_lost_with_its_worker_is_swept_and_redone_once(
    client, world, django_capture_on_commit_callbacks
):
    """Same claim protocol as the analysis runs: a live claim is never taken over, a stale
    one is queued again by the sweep (eager here) and taken over; a second sweep sends
    nothing."""
    import datetime as dt

    from django.utils import timezone

    from labs.raw_services import _claim, raw_sweep

    client.force_login(world["a"])
    with django_capture_on_commit_callbacks(execute=False):
        upload(client, linear(duration=5.0))
    record = RawRecord.objects.get()
    assert _claim(record.pk, "dead")  # claimed, then its worker is lost
    assert raw_sweep() == 0  # its heartbeat is fresh: alive for all we know
    assert raw_recompute_execute(record_id=record.pk, delivery="other") == "running"  # held
    long_ago = timezone.now() - dt.timedelta(hours=2)
    RawRecomputation.objects.filter(record=record).update(heartbeat_at=long_ago)
    assert raw_sweep() == 1
    row = RawRecomputation.objects.get()
    assert row.status == "succeeded" and row.claimed_by not in ("", "dead")
    assert raw_sweep() == 0
    # the lost task's own redelivery, later: a no-op
    assert raw_recompute_execute(record_id=record.pk, delivery="dead") == "succeeded"
    assert RawRecomputation.objects.get().finished_at == row.finished_at


def test_a_pending_recomputation_whose_message_was_lost_is_sent_again(
    client, world, django_capture_on_commit_callbacks
):
    import datetime as dt

    from django.utils import timezone

    from labs.raw_services import raw_sweep

    client.force_login(world["a"])
    with django_capture_on_commit_callbacks(execute=False):  # the message is lost
        upload(client, linear(duration=5.0))
    assert raw_sweep() == 0  # just created
    RawRecomputation.objects.update(created_at=timezone.now() - dt.timedelta(hours=2))
    assert raw_sweep() == 1
    assert RawRecomputation.objects.get().status == "succeeded"


def test_the_upload_service_takes_values_not_a_form(world, django_capture_on_commit_callbacks):
    """raw_upload_submit is called with plain values (the page and the API both do)."""
    participant = Participant.objects.get(code="W11")
    record = linear()
    point = {"device": "MEMS 1", "axis": "X", "frequency_hz": 10.0, "bench": "linear"}
    with pytest.raises(ValidationFailed) as refused:
        raw_upload_submit(
            participant=participant, point_fields=point,
            file=SimpleUploadedFile("run1.bin", int16_bytes(record)),
            sidecar=SimpleUploadedFile("run1.bin.json", b"{not json"), user=None,
        )  # fmt: skip
    assert refused.value.errors[0]["field"] == "file"
    assert not RawRecord.objects.exists()
    with django_capture_on_commit_callbacks(execute=True):
        stored = raw_upload_submit(
            participant=participant, point_fields=point,
            file=SimpleUploadedFile("run1.bin", int16_bytes(record)),
            sidecar=SimpleUploadedFile("run1.bin.json", sidecar(record)), user=None,
        )  # fmt: skip
    assert RawRecord.objects.get() == stored


def test_an_upload_stands_when_its_recomputation_cannot_be_sent(
    client, world, monkeypatch, caplog, django_capture_on_commit_callbacks
):
    """The broker unreachable after the upload's commit: the upload is answered and kept,
    the recomputation stays pending (for raw_sweep), and the one handler logs it."""
    from kombu.exceptions import OperationalError

    def refused(args, kwargs=None, **options):
        raise OperationalError("Connection refused.")

    monkeypatch.setattr("labs.tasks.raw_recompute_task.apply_async", refused)
    client.force_login(world["a"])
    with django_capture_on_commit_callbacks(execute=True):
        response = upload(client, linear(duration=5.0))
    record = RawRecord.objects.get()
    assert response.status_code == 302
    assert record.recomputation.status == "pending"
    assert f"raw recomputation of record {record.pk}" in caplog.text
    assert "broker unreachable" in caplog.text
