"""A coordinator's import of many participants' results at once.

The file is the results table of docs/interfaces.md §1 with the ``lab`` column filled with
each row's participant code, as a coordinator's table has it. It is streamed: read
and checked ``RESULTS_IMPORT_CHUNK_ROWS`` rows at a time by the importer's own
column-wise validation (:func:`labs.importers.stream.read_chunks`), so every message
is the one a laboratory's upload would give. The checks that join chunks are done
on numpy arrays of (participant, point) keys: unknown participant codes,
duplicates within a participant (also across chunks), and completeness.

Everything is stored in one transaction. Each participant in the file gets one new
``submitted`` version, by the rule of :func:`labs.services.submission_save`: its open
draft, if any, is replaced and submitted, otherwise a new version is made; decided
versions are never touched, and older versions stay as history (the newest
is the current one). A submission needs a result for every measurement point of the
participant's scope (docs/domain.md §10; every point without one), and a row outside its
scope is refused.
Results are written chunk by chunk (``COPY`` on PostgreSQL) while no error has
been found; any error rolls everything back and raises :class:`ImportRefused`
listing the first ``MAX_LISTED_ERRORS`` problems and their total count.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np
from auditlog.models import LogEntry
from django.conf import settings
from django.contrib.auth.models import User
from django.contrib.contenttypes.models import ContentType
from django.db import connections, router, transaction
from django.db.models import Max
from django.utils import timezone

from common.errors import NotVisible, StateConflict, ValidationFailed
from common.points import POINT_LOOKUPS, point_label
from labs.importers import ImportErrors, PointKey, ResultRow, RowError, TableContext
from labs.importers.errors import MAX_LISTED_ERRORS, more_problems
from labs.importers.stream import Chunk, read_chunks
from labs.models import Participant, Result, Submission
from labs.selectors import participant_points, scope_text, table_context
from labs.services import results_insert, results_sql
from proficiency.models import Comparison, ComparisonStatus

CHUNK_ROWS = 50_000
#: A coordinator imports into an open round, or a closed one not yet analysed (a
#: national programme collecting results outside the service, a past round migrated).
IMPORTABLE = (ComparisonStatus.OPEN, ComparisonStatus.CLOSED)
DUPLICATE = (
    "duplicate of row {}: same lab, device, axis, frequency_hz, bench, direction and amplitude_m_s2"
)
St = Submission.Status


class ImportRefused(ValidationFailed):
    """Nothing was stored; ``errors`` lists the first problems, ``total`` counts them all."""

    def __init__(self, errors: list[RowError], total: int) -> None:
        listed = f" (the first {len(errors):,} are listed)" if total > len(errors) else ""
        s = "s" if total != 1 else ""
        more = more_problems(total - len(errors))
        super().__init__(
            f"The results were not stored: {total:,} problem{s} found{listed}.",
            errors=[e.as_dict() for e in errors]
            + ([{"row": None, "field": None, "message": more}] if more else []),
        )
        self.row_errors, self.total = errors, total


@dataclass(frozen=True)
class ImportSummary:
    comparison: str
    participants: int
    rows: int
    new_versions: int
    drafts_submitted: int


def results_import(
    *,
    comparison: Comparison,
    file: BinaryIO | str | os.PathLike[str],
    user: User | None,
    filename: str | None = None,
    chunk_rows: int | None = None,
) -> ImportSummary:
    """Import a coordinator's results table for ``comparison``, all or nothing.

    ``user`` must coordinate the comparison (or be a superuser); ``None`` is the
    operator at the command line. Raises :class:`ImportRefused` (400) listing the
    problems, ``StateConflict`` (409) outside :data:`IMPORTABLE`, ``NotVisible`` (404)
    for anyone else.
    """
    _check_coordinator(comparison, user)
    rows = (
        chunk_rows
        if chunk_rows
        else int(getattr(settings, "RESULTS_IMPORT_CHUNK_ROWS", CHUNK_ROWS))
    )
    with _opened(file, filename) as (stream, name), transaction.atomic():
        locked = Comparison.objects.select_for_update().get(pk=comparison.pk)
        if locked.status not in IMPORTABLE:
            raise StateConflict(
                f"Comparison {locked.code} is {locked.status}: results can be imported while "
                "it is open or closed (move an analysed comparison back to closed first)."
            )
        state = _Import(locked, user, _Writer())
        try:
            for chunk in read_chunks(stream, filename=name, context=state.context, chunk_rows=rows):
                state.take(chunk)
        except ImportErrors as exc:  # the file cannot be read at all (header, encoding)
            state.errors.add(exc.errors, exc.total)
        finally:
            state.writer.close()
        summary = state.finish(name)
    return summary


def _check_coordinator(comparison: Comparison, user: User | None) -> None:
    if user is None or getattr(user, "is_superuser", False):
        return
    if not comparison.coordinators.filter(pk=user.pk).exists():
        raise NotVisible(f"No comparison {comparison.code!r} that you coordinate.")


@contextmanager
def _opened(
    file: BinaryIO | str | os.PathLike[str], filename: str | None
) -> Iterator[tuple[BinaryIO, str | None]]:
    if isinstance(file, str | os.PathLike):
        with open(file, "rb") as stream:
            yield stream, filename or os.fspath(file)
    else:
        yield file, filename or getattr(file, "name", None)


class _Errors:
    """The first ``cap`` problems and the count of all of them."""

    def __init__(self, cap: int) -> None:
        self.cap, self.total = cap, 0
        self.listed: list[RowError] = []

    def add(self, errors: list[RowError], total: int | None = None) -> None:
        """``total``: how many problems ``errors`` stands for, when it lists only the first."""
        self.total += len(errors) if total is None else total
        room = self.cap - len(self.listed)
        if room > 0:
            self.listed.extend(sorted(errors, key=lambda e: e.row or 0)[:room])


class _Seen:
    """(participant, point) keys seen so far, sorted, with the row that first gave each."""

    def __init__(self) -> None:
        self.keys = np.empty(0, np.int64)
        self.rows = np.empty(0, np.int64)

    def add(self, keys: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Record a chunk's keys; the rows repeating a key and the earlier row of each."""
        order = np.argsort(keys, kind="stable")
        k, r = keys[order], rows[order]
        first = np.ones(len(k), bool)
        first[1:] = k[1:] != k[:-1]
        earlier = r[np.maximum.accumulate(np.where(first, np.arange(len(k)), 0))]
        at = np.searchsorted(self.keys, k)
        pos = at.clip(max=max(len(self.keys) - 1, 0))
        known = (self.keys[pos] == k) if len(self.keys) else np.zeros(len(k), bool)
        earlier = np.where(known, self.rows[pos] if len(self.keys) else 0, earlier)
        repeat = known | ~first
        fresh = first & ~known
        # Both sides are sorted: inserting keeps the order without sorting again.
        self.keys = np.insert(self.keys, at[fresh], k[fresh])
        self.rows = np.insert(self.rows, at[fresh], r[fresh])
        return r[repeat], earlier[repeat]


class _Writer:
    """Writes a chunk's results; on PostgreSQL in a second thread, so that the server stores
    one chunk (COPY, indexes, the foreign-key checks made immediate) while this process
    reads and checks the next. The thread uses the transaction's own connection, whose
    lock (psycopg) makes every other query wait until the COPY is done."""

    def __init__(self) -> None:
        self.connection = connections[router.db_for_write(Result)]
        threaded = self.connection.vendor == "postgresql"
        self.pool = ThreadPoolExecutor(1, thread_name_prefix="import-copy") if threaded else None
        self.pending: Future[None] | None = None
        self.sql = results_sql(self.connection, copy=True) if threaded else ""
        if threaded:
            with self.connection.cursor() as cursor:
                cursor.execute("SET CONSTRAINTS ALL IMMEDIATE")  # checked per COPY, in the thread

    def write(self, values: list[tuple[object, ...]]) -> None:
        self.wait()
        if self.pool is None:
            results_insert(values)
        else:
            raw = self.connection.connection
            self.pending = self.pool.submit(self._copy, raw, self.sql, values)

    @staticmethod
    def _copy(raw: object, sql: str, values: list[tuple[object, ...]]) -> None:
        with raw.cursor() as cursor, cursor.copy(sql) as copy:  # type: ignore[attr-defined]
            for value in values:
                copy.write_row(value)

    def wait(self) -> None:
        """Raise here what the last write raised (the transaction then rolls back)."""
        pending, self.pending = self.pending, None
        if pending is not None:
            pending.result()

    def close(self) -> None:
        try:
            self.wait()
        finally:
            if self.pool is not None:
                self.pool.shutdown()


class _Import:
    """One import in progress: the comparison's participants and points, what was stored."""

    def __init__(self, comparison: Comparison, user: User | None, writer: _Writer) -> None:
        self.comparison, self.user, self.now = comparison, user, timezone.now()
        self.writer = writer
        self.context: TableContext = table_context(comparison)
        self._points(comparison)
        self._participants(comparison)
        self.errors = _Errors(getattr(settings, "RESULTS_IMPORT_MAX_ERRORS", MAX_LISTED_ERRORS))
        self.seen = _Seen()
        self.rows = 0
        self.created: list[tuple[int, int, int]] = []  # (participant index, submission, version)
        self.drafts_submitted: list[tuple[int, int, int]] = []

    def _points(self, comparison: Comparison) -> None:
        fields = (*POINT_LOOKUPS, "amplitude_m_s2")
        pk_by_key = {
            PointKey.from_fields(key[:-1], key[-1]): pk
            for pk, *key in comparison.measurement_points.values_list("pk", *fields).iterator(
                chunk_size=10_000
            )
        }
        self.point_keys = list(self.context.points or ())
        self.point_pks = [pk_by_key[p] for p in self.point_keys]
        self.point_index = {p: i for i, p in enumerate(self.point_keys)}
        self.row_point: dict[PointKey, int] = {}  # memo: a row's point -> index

    def _participants(self, comparison: Comparison) -> None:
        """Every participant, locked so no lab's submission collides with a version here."""
        found = list(
            Participant.objects.select_for_update()
            .filter(comparison=comparison)
            .order_by("pk")
            .values_list("pk", "code")
        )
        self.participant_pks = [pk for pk, _ in found]
        self.codes = [code for _, code in found]
        self.by_code = {code.casefold(): i for i, (_, code) in enumerate(found)}
        submissions = Submission.objects.filter(participant__comparison=comparison)
        self.last_version = dict(
            submissions.values("participant")
            .annotate(v=Max("version"))
            .values_list("participant", "v")
        )
        self.draft = dict(
            submissions.filter(status=St.DRAFT).order_by("version").values_list("participant", "pk")
        )
        self.submission_of = np.zeros(len(found), np.int64)
        self._scopes(comparison, found)

    def _scopes(self, comparison: Comparison, found: list[tuple[int, str]]) -> None:
        """Per participant with a scope (docs/domain.md §10), by index: which of the points
        it reports (a mask over ``point_keys``) and the scope in words; one query for the
        scopes, two more per participant that has one."""
        self.scope_mask: dict[int, np.ndarray] = {}
        self.scope_words: dict[int, str] = {}
        index_of = {pk: i for i, (pk, _) in enumerate(found)}
        with_devices = set(
            Participant.scope_devices.through.objects.filter(
                participant__comparison=comparison
            ).values_list("participant_id", flat=True)
        )
        point_index = {pk: i for i, pk in enumerate(self.point_pks)}
        for pk, benches, axes, frequencies in Participant.objects.filter(
            comparison=comparison
        ).values_list("pk", "scope_benches", "scope_axes", "scope_frequencies_hz"):
            if not (pk in with_devices or benches or axes or frequencies):
                continue
            scoped = Participant(pk=pk, comparison_id=comparison.pk, scope_benches=benches,
                                 scope_axes=axes, scope_frequencies_hz=frequencies)  # fmt: skip
            mask = np.zeros(len(self.point_pks), bool)
            chosen = participant_points(scoped).values_list("pk", flat=True)
            mask[[point_index[p] for p in chosen]] = True
            self.scope_mask[index_of[pk]] = mask
            self.scope_words[index_of[pk]] = scope_text(scoped)

    # --- one chunk -----------------------------------------------------------------------------

    def take(self, chunk: Chunk) -> None:
        """Check a chunk against the participants and the rows before it; store it if all is
        well so far."""
        problems = list(chunk.errors)
        keep, parts, points = [], [], []
        for row in chunk.rows:
            index = self.by_code.get((row.lab or "").casefold())
            if index is None:
                problems.append(RowError(row.row, "lab", self._unknown(row.lab)))
                continue
            point = self._point(row)
            mask = self.scope_mask.get(index)
            if mask is not None and not mask[point]:
                problems.append(RowError(row.row, None, (
                    f"{point_label(self.point_keys[point])} is not in the scope of "
                    f"{self.codes[index]} ({self.scope_words[index]})")))  # fmt: skip
                continue
            keep.append(row)
            parts.append(index)
            points.append(point)
        numbers = np.fromiter((r.row for r in keep), np.int64, len(keep))
        keys = np.asarray(parts, np.int64) * len(self.point_keys) + np.asarray(points, np.int64)
        repeated, earlier = self.seen.add(keys, numbers)
        problems.extend(
            RowError(int(n), None, DUPLICATE.format(int(e)))
            for n, e in zip(repeated, earlier, strict=True)
        )
        self.errors.add(problems)
        if not self.errors.total:
            self._store(keep, parts, points)

    def _unknown(self, code: str | None) -> str:
        return (
            f"unknown participant code {code!r} in {self.comparison.code}; the codes are listed "
            "on the comparison's participants page"
        )

    def _point(self, row: ResultRow) -> int:
        """The index of the one point the row fits (the validation made sure there is one)."""
        key = row.point
        index = self.row_point.get(key)
        if index is None:
            index = self.row_point[key] = self.point_index[self.context.matching_points(row)[0]]
        return index

    def _store(self, rows: list[ResultRow], parts: list[int], points: list[int]) -> None:
        self._ensure_submissions(np.unique(np.asarray(parts, np.int64)))
        submission_of, point_pks = self.submission_of.tolist(), self.point_pks
        self.writer.write(
            [
                (
                    submission_of[p],
                    point_pks[i],
                    r.sensitivity,
                    r.unit,
                    r.expanded_uncertainty,
                    r.coverage_factor,
                    r.dof,
                    r.note,
                    r.repeat_sd,
                    r.n_repeats,
                    r.expanded_uncertainty_entered,
                    r.measured_on,
                )
                for r, p, i in zip(rows, parts, points, strict=True)
            ]
        )
        self.rows += len(rows)

    def _ensure_submissions(self, indexes: np.ndarray) -> None:
        """A submitted version for each participant seen for the first time."""
        self.writer.wait()
        new = [int(i) for i in indexes if not self.submission_of[i]]
        drafts = [(i, self.draft[self.participant_pks[i]]) for i in new
                  if self.participant_pks[i] in self.draft]  # fmt: skip
        if drafts:
            self._submit_drafts(drafts)
        fresh = [i for i in new if self.participant_pks[i] not in self.draft]
        made = Submission.objects.bulk_create(
            [Submission(participant_id=self.participant_pks[i], version=self._next_version(i),
                        status=St.SUBMITTED, source=Submission.Source.FILE,
                        submitted_by=self.user, submitted_at=self.now) for i in fresh],
            batch_size=1_000,
        )  # fmt: skip
        for i, submission in zip(fresh, made, strict=True):
            self.submission_of[i] = submission.pk
            self.created.append((i, submission.pk, submission.version))

    def _next_version(self, index: int) -> int:
        return self.last_version.get(self.participant_pks[index], 0) + 1

    def _submit_drafts(self, drafts: list[tuple[int, int]]) -> None:
        """An open draft is replaced and submitted, as a laboratory's own submission does."""
        pks = [pk for _, pk in drafts]
        for start in range(0, len(pks), 500):
            batch = pks[start : start + 500]
            Result.objects.filter(submission_id__in=batch).delete()
            Submission.objects.filter(pk__in=batch, status=St.DRAFT).update(
                status=St.SUBMITTED, source=Submission.Source.FILE, submitted_by=self.user,
                submitted_at=self.now,
            )  # fmt: skip
        versions = dict(Submission.objects.filter(pk__in=pks).values_list("pk", "version"))
        for i, pk in drafts:
            self.submission_of[i] = pk
            self.drafts_submitted.append((i, pk, versions[pk]))

    # --- the end -------------------------------------------------------------------------------

    def finish(self, filename: str | None) -> ImportSummary:
        """Completeness, then the audit trail; raise :class:`ImportRefused` on any problem."""
        if not self.errors.total and not len(self.seen.keys):
            self.errors.add([RowError(None, None, "the table has no data rows")])
        if not self.errors.total:  # as an upload: completeness once every row is valid
            self.errors.add(self._missing())
        if self.errors.total:
            raise ImportRefused(self.errors.listed, self.errors.total)
        self._log(filename)
        return ImportSummary(
            comparison=self.comparison.code,
            participants=len(self.created) + len(self.drafts_submitted),
            rows=self.rows,
            new_versions=len(self.created),
            drafts_submitted=len(self.drafts_submitted),
        )

    def _missing(self) -> list[RowError]:
        """One error per measurement point a participant in the file has no result for."""
        n = len(self.point_keys)
        participant = self.seen.keys // max(n, 1)
        counts = np.bincount(participant, minlength=len(self.codes))
        errors: list[RowError] = []
        for index in np.flatnonzero(counts > 0):
            mask = self.scope_mask.get(int(index))
            if mask is None and counts[index] >= n:
                continue
            expected = np.arange(n) if mask is None else np.flatnonzero(mask)
            of = "" if mask is None else " of its scope"
            have = self.seen.keys[participant == index] % n
            for i in np.setdiff1d(expected, have):
                p = self.point_keys[i]
                errors.append(RowError(None, "lab", (
                    f"{self.codes[index]}: missing result for {p.device}, {p.axis}, "
                    f"{p.frequency_hz:g} Hz, {p.bench} {p.direction}; a submission needs a "
                    f"result for every measurement point{of}")))  # fmt: skip
                if len(errors) > self.errors.cap:
                    return errors
        return errors

    def _log(self, filename: str | None) -> None:
        """The audit trail a submission made one at a time would leave, written in bulk,
        and one entry on the comparison naming the import."""
        actor = self.user if getattr(self.user, "pk", None) else None
        kind = ContentType.objects.get_for_model(Submission)

        def entry(index: int, pk: int, version: int, action: int, changes: dict) -> LogEntry:
            return LogEntry(
                content_type=kind, object_pk=str(pk), object_id=pk, actor=actor, action=action,
                object_repr=f"{self.codes[index]} ({self.comparison.code}) v{version} (submitted)",
                timestamp=self.now, changes=changes,
            )  # fmt: skip

        created = {"status": ["None", St.SUBMITTED], "source": ["None", Submission.Source.FILE]}
        entries = [
            entry(i, pk, v, LogEntry.Action.CREATE, {**created, "version": ["None", str(v)]})
            for i, pk, v in self.created
        ] + [
            entry(i, pk, v, LogEntry.Action.UPDATE, {"status": [St.DRAFT, St.SUBMITTED]})
            for i, pk, v in self.drafts_submitted
        ]
        LogEntry.objects.bulk_create(entries, batch_size=1_000)
        what = f"{self.rows} results of {len(entries)} participants from "
        LogEntry.objects.log_create(
            self.comparison,
            force_log=True,
            action=LogEntry.Action.ACCESS,
            changes={"results_imported": [None, what + os.path.basename(filename or "a file")]},
            actor=actor,
        )
