"""Services of the laboratory side: participation codes, submission life cycle."""

from __future__ import annotations

import datetime as dt
import hashlib
import math
import secrets
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

from django.conf import settings
from django.contrib.auth.models import User
from django.db import IntegrityError, connections, router, transaction
from django.db.backends.base.base import BaseDatabaseWrapper
from django.utils import timezone

from common.errors import InvalidTransition, KeyReused, StateConflict, ValidationFailed
from common.points import format_number, point_label
from common.sizes import counted
from labs.importers import (
    ImportErrors,
    PointKey,
    ResultRow,
    missing_points,
    parse_rows,
    parse_table,
)
from labs.models import (
    Enrolment,
    LabAPIKey,
    Laboratory,
    Participant,
    Result,
    Submission,
    SubmissionKey,
)
from labs.notices import notify_invited, notify_opened, notify_receipt
from labs.selectors import ComparisonTable, comparison_table, scope_levels_filter
from proficiency import services as proficiency_services
from proficiency.models import Axis, Bench, Comparison, ComparisonStatus, Device

CODE_PREFIX = "L"


def participant_code_new(*, comparison: Comparison) -> str:
    """A random code ``L`` + two digits not yet used in this comparison.

    Drawn with ``secrets`` so it carries nothing of the laboratory (not its name,
    id or join order) and differs between comparisons.  With more than 99
    participants the codes grow to three, then four digits.
    """
    used = set(comparison.participants.values_list("code", flat=True))
    for digits in (2, 3, 4):
        free = [f"{CODE_PREFIX}{n:0{digits}d}" for n in range(1, 10**digits)]
        free = [c for c in free if c not in used]
        if free:
            return secrets.choice(free)
    raise StateConflict(f"Comparison {comparison.code} has no participant codes left.")


def participant_add(
    *, comparison: Comparison, laboratory: Laboratory, is_reference: bool = False
) -> Participant:
    """Invite a laboratory (idempotent: an existing participation is returned unchanged)."""
    existing = Participant.objects.filter(comparison=comparison, laboratory=laboratory).first()
    if existing:
        return existing
    for _ in range(5):  # a concurrent invitation may take the same random code
        try:
            with transaction.atomic():
                return Participant.objects.create(
                    comparison=comparison,
                    laboratory=laboratory,
                    code=participant_code_new(comparison=comparison),
                    is_reference=is_reference,
                )
        except IntegrityError:
            existing = Participant.objects.filter(
                comparison=comparison, laboratory=laboratory
            ).first()
            if existing:
                return existing
    raise StateConflict(f"Could not allocate a participant code in {comparison.code}; retry.")


@dataclass(frozen=True)
class Scope:
    """What a participant measures (docs/domain.md §10), as given by a coordinator: devices
    (rows or names), benches, axes, frequencies; an empty list allows every value."""

    devices: Sequence[Device | str] = ()
    benches: Sequence[str] = ()
    axes: Sequence[str] = ()
    frequencies_hz: Sequence[float] = ()

    @classmethod
    def of(cls, data: Mapping[str, Any]) -> Scope:
        """The scope of a form's cleaned data (the invitation's, the scope page's and the
        application's forms have these four fields)."""
        return cls(
            devices=list(data["devices"]), benches=data["benches"], axes=data["axes"],
            frequencies_hz=data["frequencies_hz"],
        )  # fmt: skip


@dataclass(frozen=True)
class _CleanScope:
    devices: list[Device]
    benches: list[str]
    axes: list[str]
    frequencies_hz: list[float]


#: The most values one level of a scope may list (a round has far fewer levels)
SCOPE_MAX_VALUES = 1_000


def _scope_clean(comparison: Comparison, scope: Scope) -> _CleanScope:
    """The scope checked against ``comparison``: its devices, known benches and axes, and
    frequencies of its points (taken at the points' value); ValidationFailed naming every
    bad value, and when the comparison has points but the scope holds none of them."""
    too_many = [
        {"row": None, "field": name,
         "message": f"{len(values)} values; a scope lists at most {SCOPE_MAX_VALUES}"}
        for name, values in (("devices", scope.devices), ("benches", scope.benches),
                             ("axes", scope.axes), ("frequencies_hz", scope.frequencies_hz))
        if len(values) > SCOPE_MAX_VALUES
    ]  # fmt: skip
    if too_many:  # before any check: its work and its answer stay bounded
        raise ValidationFailed("The scope lists too many values.", errors=too_many)
    errors: list[dict[str, object]] = []
    by_name = {" ".join(d.name.split()).casefold(): d for d in comparison.devices.all()}
    devices: list[Device] = []
    for given in scope.devices:
        if isinstance(given, Device):
            found = given if given.comparison_id == comparison.pk else None
        else:
            found = by_name.get(" ".join(str(given).split()).casefold())
        if found is None:
            errors.append({"row": None, "field": "devices",
                           "message": f"{given} is not a device of {comparison.code}"})  # fmt: skip
        elif found not in devices:
            devices.append(found)
    benches = list(dict.fromkeys(scope.benches))
    errors += [
        {"row": None, "field": "benches",
         "message": f"unknown bench {b!r}; one of {', '.join(Bench.values)}"}
        for b in benches if b not in Bench.values
    ]  # fmt: skip
    axes = list(dict.fromkeys(a.upper() if isinstance(a, str) else a for a in scope.axes))
    errors += [
        {"row": None, "field": "axes", "message": f"unknown axis {a!r}; one of X, Y, Z"}
        for a in axes if a not in Axis.values
    ]  # fmt: skip
    known = sorted(set(comparison.measurement_points.values_list("frequency_hz", flat=True)))
    frequencies: list[float] = []
    for f in scope.frequencies_hz:
        if not (isinstance(f, int | float) and math.isfinite(f) and f > 0):
            errors.append({"row": None, "field": "frequencies_hz",
                           "message": f"{f!r} is not a frequency > 0"})  # fmt: skip
            continue
        same = [k for k in known if math.isclose(k, f, rel_tol=1e-9)] if known else [float(f)]
        if not same:
            errors.append({"row": None, "field": "frequencies_hz",
                           "message": f"{format_number(f)} Hz is not a frequency of "
                           f"{comparison.code}"})  # fmt: skip
        elif same[0] not in frequencies:
            frequencies.append(same[0])
    if errors:
        raise ValidationFailed("The scope does not fit the comparison.", errors=errors)
    clean = _CleanScope(devices, benches, axes, frequencies)
    points = comparison.measurement_points
    levels = scope_levels_filter(
        device_ids=[d.pk for d in devices], benches=benches, axes=axes, frequencies_hz=frequencies
    )
    if points.exists() and not points.filter(levels).exists():
        raise ValidationFailed(
            f"The scope holds none of the measurement points of {comparison.code}.",
            errors=[{"row": None, "field": None, "message": "no measurement point in the scope"}],
        )
    return clean


def _scope_store(row: Participant | Enrolment, scope: _CleanScope) -> None:
    """Store a checked scope on a participant, or on an application (same fields)."""
    row.scope_benches = scope.benches
    row.scope_axes = scope.axes
    row.scope_frequencies_hz = scope.frequencies_hz
    row.save(update_fields=["scope_benches", "scope_axes", "scope_frequencies_hz"])
    row.scope_devices.set(scope.devices)


def scope_change_check(comparison: Comparison) -> None:
    """StateConflict (409) once the comparison's submission deadline has passed: the
    laboratories plan and report against their scope until then."""
    deadline = comparison.submission_deadline
    if deadline is not None and timezone.now() > deadline:
        raise StateConflict(
            f"The submission deadline of {comparison.code} passed on "
            f"{deadline:%Y-%m-%d %H:%M} UTC: scopes can no longer be changed."
        )


@transaction.atomic
def participant_scope_set(*, participant: Participant, scope: Scope) -> Participant:
    """Set what ``participant`` measures (an empty :class:`Scope`: every point), until the
    submission deadline; all or nothing, under the participant's row lock."""
    comparison = participant.comparison
    scope_change_check(comparison)
    clean = _scope_clean(comparison, scope)
    Participant.objects.select_for_update().get(pk=participant.pk)
    _scope_store(participant, clean)
    return participant


@transaction.atomic
def participants_invite(
    *,
    comparison: Comparison,
    laboratories: Sequence[Laboratory],
    scope: Scope | None = None,
    notify: bool = True,
) -> list[Participant]:
    """Invite ``laboratories`` to ``comparison``, all or none, in one transaction; each new
    participant gets a random code (:func:`participant_code_new`) and ``scope`` (none: every
    point), an existing participation is returned unchanged, its scope too (so a repeated
    invitation is harmless; :func:`participant_scope_set` changes a scope). Each new
    participant's laboratory is sent an invitation notice (docs/lifecycles.md §6) unless
    ``notify`` is False (the demo's data, loaded for a round long closed)."""
    if not laboratories:
        raise ValidationFailed(
            f"Choose at least one laboratory to invite to {comparison.code}.",
            errors=[{"field": "laboratories", "message": "at least one laboratory"}],
        )
    clean = _scope_clean(comparison, scope) if scope is not None else None
    before = set(comparison.participants.values_list("pk", flat=True))
    added = [participant_add(comparison=comparison, laboratory=lab) for lab in laboratories]
    for participant in added:
        if participant.pk in before:
            continue
        before.add(participant.pk)
        if clean is not None:
            _scope_store(participant, clean)
        if notify:
            notify_invited(participant)
    return added


@transaction.atomic
def comparison_move(*, comparison: Comparison, to: str) -> Comparison:
    """A coordinator's status change (``proficiency.services.comparison_transition``, the
    one life cycle); on opening, every participant is sent a notice (docs/lifecycles.md
    §6). Publication has its own service (``analysis.publication``)."""
    moved = proficiency_services.comparison_transition(comparison=comparison, to=to)
    if moved.status == ComparisonStatus.OPEN:
        notify_opened(moved)
    return moved


St = Submission.Status

# The one place where the submission life cycle is defined. Decided versions are
# never edited: a correction is a new version.
SUBMISSION_TRANSITIONS: dict[str, frozenset[str]] = {
    St.DRAFT: frozenset({St.SUBMITTED}),
    St.SUBMITTED: frozenset({St.ACCEPTED, St.REJECTED}),
    St.ACCEPTED: frozenset(),
    St.REJECTED: frozenset(),
}


@transaction.atomic
def submission_transition(*, submission: Submission, to: str, message: str = "") -> Submission:
    """Move a submission to ``to`` if its life cycle allows it, under a row lock."""
    locked = Submission.objects.select_for_update().get(pk=submission.pk)
    if Submission.participant.is_cached(submission):
        # the same participant row (a version never changes participant): the audit log's
        # text of the version (str) then needs no query for the participant and comparison
        locked.participant = submission.participant
    if to not in SUBMISSION_TRANSITIONS[locked.status]:
        allowed = ", ".join(sorted(SUBMISSION_TRANSITIONS[locked.status])) or "none (decided)"
        raise InvalidTransition(
            f"Submission version {locked.version} of {locked.participant.code} cannot go from "
            f"{locked.status} to {to}; allowed next status: {allowed}."
        )
    now = timezone.now()
    locked.status = to
    if to == St.SUBMITTED:
        locked.submitted_at = now
    else:
        locked.decided_at = now
        locked.message = message
    locked.save(update_fields=["status", "submitted_at", "decided_at", "message"])
    return locked


def submission_window_check(comparison: Comparison) -> None:
    """StateConflict (409) unless the comparison is open and its deadline has not passed."""
    if comparison.status != ComparisonStatus.OPEN:
        raise StateConflict(
            f"Comparison {comparison.code} is {comparison.status}: results can be submitted "
            "only while it is open."
        )
    deadline = comparison.submission_deadline
    if deadline is not None and timezone.now() > deadline:
        raise StateConflict(
            f"The submission deadline of {comparison.code} passed on "
            f"{deadline:%Y-%m-%d %H:%M} UTC; ask the coordinator to extend it."
        )


def _missing_error(missing: list[PointKey], table: ComparisonTable) -> ValidationFailed:
    listed = [
        {"row": None, "field": None, "message": f"missing result for {point_label(p)}"}
        for p in missing
    ]
    scope = table.context.scope_text
    where = f" of your scope ({scope})" if table.context.scope is not None else ""
    return ValidationFailed(
        f"{counted(len(missing), 'measurement point')}{where} "
        f"{'has' if len(missing) == 1 else 'have'} no result; a partial submission can only be "
        "saved as a draft.",
        errors=listed,
    )


@transaction.atomic
def submission_save(
    *,
    participant: Participant,
    rows: list[ResultRow],
    source: str,
    user: User | None,
    submit: bool,
    table: ComparisonTable | None = None,
    idempotency_key: str = "",
) -> Submission:
    """Store a participant's results, all or nothing (the one path for grid, upload and API).

    ``rows`` come from the importer, validated against ``table`` (the comparison's
    :func:`comparison_table` with the participant's scope: read here when not given; the
    points of an open comparison do not change).  Saving a draft replaces the participant's
    open draft, if any; submitting needs a result for every measurement point of its scope
    (every point without one) and makes the draft (or a new
    version) ``submitted``.  Decided versions are never touched: a correction is a new
    version.  The participant row is locked so versions never collide.

    Retries answer the version already stored (marked ``replayed = True``), decided under
    the same lock, so two identical requests at once store one version: a request with
    the ``idempotency_key`` of an earlier one (kept ``IDEMPOTENCY_KEY_HOURS``) answers its
    version, or :class:`KeyReused` (422) when its content or submit flag differ; without a
    key, results identical to the latest version's from the same source, submitted again
    within ``SUBMISSION_DEDUP_SECONDS`` of it (or saved again as the same draft), answer it.
    """
    Participant.objects.select_for_update().get(pk=participant.pk)
    comparison = participant.comparison
    table = table or comparison_table(comparison, participant)
    values = _result_values(rows, table)
    content = _content_sha256(values)
    fingerprint = hashlib.sha256(f"{content} submit={bool(submit)}".encode()).hexdigest()
    now = timezone.now()
    if idempotency_key and (keyed := _keyed(participant, idempotency_key, fingerprint, now)):
        return _replayed(keyed, participant)
    # the open draft is always the latest version: a new version is made only when there
    # is none, and a draft only ever becomes submitted
    latest = participant.submissions.order_by("-version").first()
    if not idempotency_key and _same_as(latest, content, source, submit, now):
        assert latest is not None
        return _replayed(latest, participant)
    submission_window_check(comparison)
    if submit and (missing := missing_points(rows, table.context)):
        raise _missing_error(missing, table)
    if latest is not None and latest.status == St.DRAFT:
        draft = latest
        # a draft's results are never scored (only accepted versions are analysed): one
        # DELETE, without the collector reading every row to look for scores
        _results_delete(draft)
        draft.source, draft.submitted_by, draft.content_sha256 = source, user, content
        draft.save(update_fields=["source", "submitted_by", "content_sha256"])
        n_results = _results(draft, values)
        saved = submission_transition(submission=draft, to=St.SUBMITTED) if submit else draft
    else:
        # a new version is stored submitted at once when submitted (no draft step)
        saved = Submission.objects.create(
            participant=participant,
            version=(latest.version if latest else 0) + 1,
            source=source,
            submitted_by=user,
            status=St.SUBMITTED if submit else St.DRAFT,
            submitted_at=timezone.now() if submit else None,
            content_sha256=content,
        )
        n_results = _results(saved, values)
    if idempotency_key:
        SubmissionKey.objects.create(
            participant=participant, key=idempotency_key, fingerprint=fingerprint, submission=saved
        )
    # the version's result count, as the history annotates it (the API's n_results): the
    # rows just stored are all its results (a draft's earlier ones were deleted above)
    saved.n_results = n_results  # type: ignore[attr-defined]
    if saved.status == St.SUBMITTED:
        saved.participant = participant
        notify_receipt(saved, n_results)
    saved.replayed = False  # type: ignore[attr-defined]
    return saved


def _keyed(
    participant: Participant, key: str, fingerprint: str, now: dt.datetime
) -> Submission | None:
    """The version an earlier request with this key made, if the key is still kept; an
    expired key is forgotten (deleted) and the request is new."""
    entry = SubmissionKey.objects.filter(participant=participant, key=key).first()
    if entry is None:
        return None
    if entry.created_at < now - dt.timedelta(hours=settings.IDEMPOTENCY_KEY_HOURS):
        entry.delete()
        return None
    if entry.fingerprint != fingerprint:
        raise KeyReused(
            f"The Idempotency-Key {key!r} was already used at {entry.created_at:%Y-%m-%d %H:%M} "
            "UTC with other results or another submit flag; send a new key for a new request.",
            errors=[{"field": "Idempotency-Key", "message": "already used for another request"}],
        )
    return Submission.objects.get(pk=entry.submission_id)


def _same_as(
    latest: Submission | None, content: str, source: str, submit: bool, now: dt.datetime
) -> bool:
    """Whether a request without a key repeats ``latest``: the same results from the same
    source (web grid, file, API) submitted again (``latest`` submitted or accepted within
    ``SUBMISSION_DEDUP_SECONDS``), or the same draft saved again (nothing would change)."""
    if latest is None or not latest.content_sha256 or latest.content_sha256 != content:
        return False
    if latest.source != source:
        return False
    if not submit:
        return latest.status == St.DRAFT
    window = dt.timedelta(seconds=settings.SUBMISSION_DEDUP_SECONDS)
    recent = latest.submitted_at is not None and latest.submitted_at >= now - window
    return latest.status in (St.SUBMITTED, St.ACCEPTED) and recent


def _replayed(submission: Submission, participant: Participant) -> Submission:
    submission.participant = participant
    submission.replayed = True  # type: ignore[attr-defined]
    return submission


def _content_sha256(values: Sequence[tuple[object, ...]]) -> str:
    """SHA-256 of the results' values by measurement point (``repr`` of each value: floats
    exactly), whatever their order or source (grid, file, JSON).

    The U as entered (the last value but one) counts only when the lab gave U in per cent,
    the date measured (the last) only when the lab stated one: a result without them
    hashes the tuple it hashed before they were kept, so an old submission sent again
    still answers its version (docs/lifecycles.md §2)."""
    digest = hashlib.sha256()
    for value in sorted(values, key=lambda v: v[0]):  # type: ignore[arg-type, return-value]
        *kept, entered, measured_on = value
        hashed = (*kept, entered) if entered else tuple(kept)
        digest.update(repr(hashed if measured_on is None else (*hashed, measured_on)).encode())
        digest.update(b"\n")
    return digest.hexdigest()


def _results_delete(submission: Submission) -> None:
    connection = connections[router.db_for_write(Result)]
    table = connection.ops.quote_name(Result._meta.db_table)
    column = connection.ops.quote_name(Result._meta.get_field("submission").column)
    with connection.cursor() as cursor:
        cursor.execute(f"DELETE FROM {table} WHERE {column} = %s", [submission.pk])


def _results(submission: Submission, values: list[tuple[object, ...]]) -> int:
    """Insert one :class:`Result` per value tuple (:func:`_result_values`); the count.

    One ``COPY`` on PostgreSQL, one ``executemany`` elsewhere: 100,000 model instances
    and bulk_create's per-value SQL compilation took about 4 s, this takes 0.6 s.
    The database still enforces every constraint of ``Result``.
    """
    return results_insert([(submission.pk, *v) for v in values])


def _result_values(rows: list[ResultRow], table: ComparisonTable) -> list[tuple[object, ...]]:
    """(point id, value, unit, U, k, dof, note, repeat_sd, n_repeats, U as entered, date
    measured) of each row, on the one measurement point it fits."""
    values: list[tuple[object, ...]] = []
    for row in rows:
        # The importer already refused a row fitting no point or several: never store a guess.
        matches = table.context.matching_points(row)
        if len(matches) != 1:
            raise ValidationFailed(
                f"row {row.row} does not identify one measurement point of this comparison",
                errors=[{"row": row.row, "field": None, "message": "unknown measurement point"}],
            )
        if not table.context.in_scope(matches[0]):
            raise ValidationFailed(
                f"row {row.row}: {point_label(matches[0])} is not in your scope "
                f"({table.context.scope_text})",
                errors=[{"row": row.row, "field": None, "message": "not in your scope"}],
            )
        point_id = table.point_ids[matches[0]]
        values.append(
            (point_id, row.sensitivity, row.unit, row.expanded_uncertainty,
             row.coverage_factor, row.dof, row.note, row.repeat_sd, row.n_repeats,
             row.expanded_uncertainty_entered, row.measured_on)
        )  # fmt: skip
    return values


RESULT_COLUMNS = ("submission", "measurement_point", "value", "unit", "expanded_uncertainty",
                  "coverage_factor", "dof", "note", "repeat_sd", "n_repeats",
                  "expanded_uncertainty_entered", "measured_on")  # fmt: skip


def results_insert(values: Sequence[Sequence[Any]]) -> int:
    """Insert raw :class:`Result` rows (tuples in :data:`RESULT_COLUMNS` order); the count.

    One ``COPY`` on PostgreSQL, one ``executemany`` elsewhere, inside the caller's
    transaction; the database enforces every constraint of ``Result``.
    """
    connection = connections[router.db_for_write(Result)]
    with connection.cursor() as cursor:
        if connection.vendor == "postgresql":
            with cursor.cursor.copy(results_sql(connection, copy=True)) as copy:
                for value in values:
                    copy.write_row(value)
        else:
            cursor.executemany(results_sql(connection, copy=False), values)
    return len(values)


def results_sql(connection: BaseDatabaseWrapper, *, copy: bool) -> str:
    """``COPY result (...) FROM STDIN`` or ``INSERT INTO result (...) VALUES (%s, ...)``."""
    table = connection.ops.quote_name(Result._meta.db_table)
    # the columns of concrete fields: get_field's union also holds relations without one
    names = [connection.ops.quote_name(Result._meta.get_field(n).column) for n in RESULT_COLUMNS]  # type: ignore[union-attr,arg-type]
    if copy:
        return f"COPY {table} ({', '.join(names)}) FROM STDIN"
    marks = ", ".join(["%s"] * len(names))
    return f"INSERT INTO {table} ({', '.join(names)}) VALUES ({marks})"


def _import_failed(exc: ImportErrors) -> ValidationFailed:
    """At most MAX_LISTED_ERRORS problems are listed, then one entry counting the rest."""
    n = exc.total
    listed = f" (the first {len(exc.errors):,} are listed)" if exc.more else ""
    return ValidationFailed(
        f"The results were not stored: {n:,} problem{'s' if n != 1 else ''} found{listed}.",
        errors=exc.as_dicts(),
    )


def submission_from_file(
    *,
    participant: Participant,
    data: bytes,
    filename: str | None,
    user: User | None,
    submit: bool,
    idempotency_key: str = "",
) -> Submission:
    """A CSV/XLSX upload (docs/interfaces.md §1): parse against the comparison, then save."""
    table = comparison_table(participant.comparison, participant)
    try:
        rows = parse_table(data, filename=filename, lab_column="forbidden", context=table.context)
    except ImportErrors as exc:
        raise _import_failed(exc) from None
    return submission_save(
        participant=participant, rows=rows, source=Submission.Source.FILE, user=user,
        submit=submit, table=table, idempotency_key=idempotency_key,
    )  # fmt: skip


def submission_from_records(
    *,
    participant: Participant,
    records: Sequence[object],
    source: str,
    user: User | None,
    submit: bool,
    idempotency_key: str = "",
) -> Submission:
    """JSON rows from the API or the web grid: same rules as a file."""
    table = comparison_table(participant.comparison, participant)
    try:
        rows = parse_rows(records, lab_column="forbidden", context=table.context)
    except ImportErrors as exc:
        raise _import_failed(exc) from None
    return submission_save(
        participant=participant, rows=rows, source=source, user=user, submit=submit,
        table=table, idempotency_key=idempotency_key,
    )  # fmt: skip


def api_key_create(
    *, laboratory: Laboratory, name: str, user: User | None
) -> tuple[LabAPIKey, str]:
    """A new key for ``laboratory``; returns the row and the key, which is never shown again."""
    name = name.strip()
    if not name:
        raise ValidationFailed("Give the key a name, e.g. the software or computer using it.")
    key_obj, key = LabAPIKey.objects.create_key(name=name, laboratory=laboratory, created_by=user)
    return cast(LabAPIKey, key_obj), key  # the library's create_key returns its base class


def api_key_revoke(*, key: LabAPIKey) -> LabAPIKey:
    """Revoke a key (kept for the record; it no longer authenticates). Idempotent."""
    if not key.revoked:
        key.revoked = True
        key.save(update_fields=["revoked"])
    return key


@transaction.atomic
def participant_set_reference(*, participant: Participant) -> Participant:
    """Make ``participant`` the one reference (pilot) laboratory of its comparison."""
    siblings = Participant.objects.filter(comparison_id=participant.comparison_id)
    siblings.exclude(pk=participant.pk).update(is_reference=False)
    siblings.filter(pk=participant.pk).update(is_reference=True)
    participant.is_reference = True
    return participant
