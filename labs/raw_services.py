"""Raw records behind a result: upload, storage by content hash, and the
recomputation job (``pending → running → succeeded | failed``).

``raw_record_upload`` validates everything a person can get wrong (which point, the
metadata, the file itself, read by the same readers as ``pt_sensitivity``) before
anything is stored, stores each file once per SHA-256, creates the record and its
pending recomputation in one transaction and enqueues ``raw_recompute_task`` after
commit.  ``raw_recompute_execute`` claims the row with a conditional UPDATE and writes
the outputs with a second conditional UPDATE, so a task delivered twice leaves one
result (the row is one per record: a OneToOne).

The claim is the analysis runs' protocol, by the same helpers (``common.jobs``): a
running row may be taken over when its heartbeat is stale or by a redelivery of the task
that claimed it, and ``raw_sweep`` (Celery beat) re-queues the rows whose worker was lost.
The claim's ``started_at`` is the token ``_finish`` checks.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from celery import uuid
from django.conf import settings
from django.contrib.auth.models import User
from django.core.files.base import ContentFile
from django.core.files.uploadedfile import UploadedFile
from django.db import IntegrityError, transaction
from django.utils import timezone

import proficiency
from analysis.core.groups import CoreInputError
from analysis.core.signals.records import SignalInputError
from common import jobs
from common.errors import RequestTooLarge, ValidationFailed
from common.jobs import heartbeat
from labs.importers.values import human_size
from labs.models import Participant, RawFile, RawRecomputation, RawRecord, Result, Submission
from labs.raw import form_metadata, read_record, sidecar_json
from labs.raw_outputs import en_number, recomputed_outputs
from labs.raw_selectors import raw_point_find

__all__ = ["en_number"]  # its home before labs.raw_outputs; callers import it from here
from labs.tasks import raw_recompute_task
from proficiency.models import MeasurementPoint

log = logging.getLogger(__name__)
R = RawRecomputation.Status
METHOD = "sine-fit"


@dataclass(frozen=True)
class Upload:
    """One uploaded raw file with its metadata (sidecar merged with form fields)."""

    content: bytes
    name: str
    meta: dict[str, Any]


def human_limit() -> str:
    return human_size(settings.RAW_UPLOAD_MAX_BYTES)


def check_size(size: int, what: str) -> None:
    if size > settings.RAW_UPLOAD_MAX_BYTES:
        raise RequestTooLarge(
            f"The {what} is {human_size(size)}; the limit for raw records is {human_limit()}."
        )


#: two files, two sidecars and the form fields on top of the files themselves
MULTIPART_SLACK_BYTES = 256 * 1024


def raw_request_limit() -> int:
    return 2 * settings.RAW_UPLOAD_MAX_BYTES + MULTIPART_SLACK_BYTES


def raw_declared_too_large(meta: Mapping[str, Any]) -> str | None:
    """The 413 message when the declared Content-Length alone is over the limit."""
    try:
        length = int(meta.get("CONTENT_LENGTH") or 0)
    except ValueError:
        length = 0
    if length <= raw_request_limit():
        return None
    return (
        f"The upload is {human_size(length)}; the limit for raw records is {human_limit()} "
        "per file. Nothing was stored."
    )


# --- upload ------------------------------------------------------------------------------


def _reported(participant: Participant, point: MeasurementPoint) -> tuple[Submission, Result]:
    """The participant's current (latest) submission and its result at ``point``."""
    submission = participant.submissions.order_by("-version").first()
    result = submission.results.filter(measurement_point=point).first() if submission else None
    if submission is None or result is None:
        raise ValidationFailed(
            f"Your current submission has no result for {point}; report the sensitivity "
            "first, then attach the raw records it came from.",
            errors=[{"field": "device", "message": "no reported result at this point"}],
        )
    return submission, result


def _complete_meta(meta: dict[str, Any], point: MeasurementPoint, field: str) -> dict[str, Any]:
    """bench and frequency_hz default to the point's; a contradiction is refused."""
    out: dict[str, Any] = {"bench": point.bench, "frequency_hz": point.frequency_hz} | meta
    for key in ("bench", "frequency_hz"):
        same = str(out[key]) == str(getattr(point, key))
        if key == "frequency_hz":
            try:
                same = math.isclose(float(out[key]), point.frequency_hz)
            except (TypeError, ValueError):
                same = True  # the reader says what is wrong with the number
        if not same:
            raise ValidationFailed(
                f"The metadata says {key} {out[key]!r} but the measurement point has "
                f"{getattr(point, key)!r}.",
                errors=[{"field": field, "message": f"{key} contradicts the measurement point"}],
            )
    return out


def _validated(upload: Upload, field: str, meta: dict[str, Any]) -> dict[str, Any]:
    check_size(len(upload.content), f"file {upload.name!r}")
    try:
        record = read_record(upload.content, upload.name, meta)
    except CoreInputError as exc:
        error = {"field": field, "message": str(exc)}
        raise ValidationFailed(str(exc), errors=[error]) from None
    return {k: list(v) if isinstance(v, tuple) else v for k, v in record.meta.items()}


def raw_file_store(content: bytes) -> RawFile:
    """The stored file with these bytes, written once (content-addressed, read-only)."""
    digest = hashlib.sha256(content).hexdigest()
    existing = RawFile.objects.filter(sha256=digest).first()
    if existing is not None:
        if not existing.file.storage.exists(existing.file.name):  # lost (a restored backup):
            _write(existing.file.storage, existing.file.name, content)  # the same bytes again
        return existing
    raw = RawFile(sha256=digest, size=len(content))
    name = raw.file.field.generate_filename(raw, digest)
    storage = raw.file.storage
    if storage.exists(name):  # left by a rolled-back upload: same hash, same bytes
        raw.file.name = name
    else:
        raw.file.save(digest, ContentFile(content), save=False)
        _read_only(storage, raw.file.name)
    try:
        with transaction.atomic():
            raw.save()
    except IntegrityError:  # stored meanwhile by a concurrent upload of the same bytes
        return RawFile.objects.get(sha256=digest)
    return raw


def _write(storage: Any, name: str, content: bytes) -> None:
    stored = storage.save(name, ContentFile(content))
    if stored != name:  # pragma: no cover - the name was checked free just before
        raise RuntimeError(f"raw file {name} was stored as {stored}")
    _read_only(storage, name)


def _read_only(storage: Any, name: str) -> None:
    with contextlib.suppress(NotImplementedError, OSError):  # not a local file system
        os.chmod(storage.path(name), 0o440)


def raw_record_upload(
    *,
    participant: Participant,
    point_fields: Mapping[str, Any],
    data: Upload,
    reference: Upload | None = None,
    user: User | None = None,
) -> RawRecord:
    """Attach raw record(s) to a point of the participant's current submission."""
    point = raw_point_find(participant, point_fields)
    submission, result = _reported(participant, point)
    meta = _validated(data, "file", _complete_meta(data.meta, point, "file"))
    ref_meta: dict[str, Any] = {}
    if reference is not None:
        base = {"frequency_hz": meta["frequency_hz"]} | reference.meta
        ref_meta = _validated(reference, "reference_file", base)
    with transaction.atomic():
        record = RawRecord.objects.create(
            participant=participant,
            submission=submission,
            measurement_point=point,
            data_file=raw_file_store(data.content),
            data_name=data.name,
            metadata=meta,
            reference_file=raw_file_store(reference.content) if reference else None,
            reference_name=reference.name if reference else "",
            reference_metadata=ref_meta,
            uploaded_by=user,
        )
        _recomputation_create(record, result)
    return record


def _recomputation_create(record: RawRecord, result: Result) -> RawRecomputation:
    recomputation = RawRecomputation.objects.create(
        record=record,
        method=METHOD,
        software_version=proficiency.__version__,
        parameters=_parameters(record),
        reported_value=result.value,
        reported_expanded_uncertainty=result.expanded_uncertainty,
        reported_coverage_factor=result.coverage_factor,
    )
    # With the broker unreachable the row stays pending and raw_sweep sends it again.
    what = f"raw recomputation of record {record.pk}"
    transaction.on_commit(lambda: jobs.send(raw_recompute_task, (record.pk,), what=what))
    return recomputation


def _parameters(record: RawRecord) -> dict[str, Any]:
    """Everything that determines the result, with the files by hash (docs/interfaces.md §2)."""
    return {
        "method": METHOD,
        "data_sha256": record.data_file.sha256,
        "data_name": record.data_name,
        "metadata": record.metadata,
        "reference_sha256": record.reference_file.sha256 if record.reference_file else None,
        "reference_name": record.reference_name,
        "reference_metadata": record.reference_metadata,
        "axis": record.measurement_point.axis,
        "direction": record.measurement_point.direction,
        "quantity": record.measurement_point.quantity,
    }


# --- recomputation -------------------------------------------------------------------------


def _claim(record_id: int, delivery: str = "") -> bool:
    """pending → running; or take over a running row whose heartbeat is stale, or that
    this very task (``delivery``, its Celery id, redelivered after its worker was lost)
    had claimed.  Each claim sets a new ``started_at``, the token ``_finish`` checks."""
    fresh = {"status": R.RUNNING, "started_at": timezone.now(), "error": ""}
    rows = RawRecomputation.objects.filter(record_id=record_id)
    return jobs.claim(rows, delivery=delivery, fresh=fresh, takeover=fresh)


def _beat(row_id: int, started_at: Any) -> None:
    """The row's heartbeat while this claim holds it (never waits for a lock)."""
    jobs.beat(RawRecomputation, row_id, status=R.RUNNING, started_at=started_at)


def raw_recompute_execute(*, record_id: int, delivery: str = "") -> str:
    """Recompute record ``record_id``; a no-op (returns the status) unless it is pending,
    or running and lost by its worker.  ``delivery``: this task's Celery id."""
    if not _claim(record_id, delivery):
        row = RawRecomputation.objects.filter(record_id=record_id).first()
        return row.status if row else "missing"
    row = RawRecomputation.objects.select_related(
        "record__measurement_point", "record__data_file", "record__reference_file"
    ).get(record_id=record_id)
    with heartbeat(lambda: _beat(row.pk, row.started_at), f"raw recomputation {row.pk}"):
        try:
            outputs = recomputed_outputs(row)
        except CoreInputError as exc:
            return _finish(row, {"status": R.FAILED, "error": str(exc)})
        except Exception as exc:  # any other error is shown too, never a silent stuck row
            log.exception("raw recomputation of record %s failed", record_id)
            return _finish(row, {"status": R.FAILED, "error": f"{type(exc).__name__}: {exc}"})
        return _finish(row, {"status": R.SUCCEEDED, **outputs})


def raw_sweep() -> int:
    """Celery beat: re-queue the recomputations silent for ``JOB_STALE_SECONDS`` (pending
    ones whose message was lost, running ones whose worker was lost).  Each is decided by
    a conditional UPDATE that moves the heartbeat to now and names the task sent, which
    may then take the claim over: two sweeps at once send it once.  The number sent."""
    rows = RawRecomputation.objects.filter(
        jobs.silent("created_at"), status__in=(R.PENDING, R.RUNNING)
    )
    sent = 0
    for pk, record_id, status, beat in rows.values_list(
        "pk", "record_id", "status", "heartbeat_at"
    ):  # fmt: skip
        task_id = uuid()
        mine = {"claimed_by": task_id} if status == R.RUNNING else {}
        if not jobs.lease(RawRecomputation.objects.all(), pk=pk, status=status, heartbeat_at=beat,
                          **mine):  # fmt: skip
            continue
        log.warning("raw recomputation of record %s silent: queued again", record_id)
        what = f"raw recomputation of record {record_id}"
        sent += jobs.send(raw_recompute_task, (record_id,), task_id=task_id, what=what)
    return sent


def _finish(row: RawRecomputation, fields: dict[str, Any]) -> str:
    """Write the outputs only if this task still owns the running row."""
    fields["finished_at"] = timezone.now()
    RawRecomputation.objects.filter(pk=row.pk, status=R.RUNNING, started_at=row.started_at).update(
        **fields
    )
    return str(RawRecomputation.objects.get(pk=row.pk).status)


def raw_upload_build(
    *, file: Any, sidecar: Any = None, fields: Mapping[str, Any] | None = None, field: str
) -> Upload:
    """An :class:`Upload` from an uploaded file, its optional JSON sidecar and the metadata
    form fields (which replace sidecar keys); 400 naming ``field`` on bad metadata."""
    check_size(file.size, f"file {file.name!r}")
    try:
        meta = sidecar_json(sidecar.read(), sidecar.name) if sidecar is not None else {}
        meta |= form_metadata(fields or {})
    except SignalInputError as exc:
        error = {"field": field, "message": str(exc)}
        raise ValidationFailed(str(exc), errors=[error]) from None
    return Upload(content=file.read(), name=os.path.basename(file.name), meta=meta)


def raw_upload_submit(
    *,
    participant: Participant,
    point_fields: Mapping[str, Any],
    file: UploadedFile,
    sidecar: UploadedFile | None = None,
    meta_fields: Mapping[str, Any] | None = None,
    reference_file: UploadedFile | None = None,
    reference_sidecar: UploadedFile | None = None,
    reference_fields: Mapping[str, Any] | None = None,
    user: User | None = None,
) -> RawRecord:
    """One upload (the page's and the API's): the record, its sidecar and metadata fields,
    optionally the reference record; :class:`ValidationFailed` naming the field at fault."""
    main = raw_upload_build(file=file, sidecar=sidecar, fields=meta_fields, field="file")
    reference = None
    if reference_file is not None:
        reference = raw_upload_build(
            file=reference_file, sidecar=reference_sidecar, fields=reference_fields,
            field="reference_file",
        )  # fmt: skip
    return raw_record_upload(
        participant=participant, point_fields=point_fields, data=main, reference=reference,
        user=user,
    )  # fmt: skip
