"""Analysis runs and their outputs (assigned values, scores), issued reports and the jobs
issuing them.

These start minimal; the coordinator and report issues grow them.
"""

from __future__ import annotations

import secrets

from django.conf import settings
from django.db import connections, models
from django.db.models import Q
from django.db.models.signals import pre_delete
from django.dispatch import receiver

from labs.models import Participant, Result
from proficiency.models import AssignedValueMethod, Comparison, MeasurementPoint


class AnalysisRun(models.Model):
    """A persisted background job: ``pending → running → succeeded | failed | cancelled``.

    ``heartbeat_at`` is the last sign of life of any task working on the run (its claim,
    a heartbeat while it works, a chunk stored): the stale-job sweep
    (``analysis.services.analysis_sweep``) re-queues the work of a run silent for longer
    than ``JOB_STALE_SECONDS``.  ``claimed_by`` is the Celery task id of the run task
    holding the run.
    """

    class Status(models.TextChoices):
        PENDING = "pending", "Pending"
        RUNNING = "running", "Running"
        SUCCEEDED = "succeeded", "Succeeded"
        FAILED = "failed", "Failed"
        CANCELLED = "cancelled", "Cancelled"

    comparison = models.ForeignKey(
        Comparison, on_delete=models.CASCADE, related_name="analysis_runs"
    )
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.PENDING)
    progress = models.PositiveSmallIntegerField(default=0)
    stage = models.CharField(max_length=40, blank=True)
    error = models.TextField(blank=True)
    parameters = models.JSONField(default=dict, blank=True)
    code_version = models.CharField(max_length=40, blank=True)
    created_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )
    created_at = models.DateTimeField(auto_now_add=True)
    started_at = models.DateTimeField(null=True, blank=True)
    finished_at = models.DateTimeField(null=True, blank=True)
    chunks_total = models.PositiveIntegerField(default=0, help_text="chunks of points planned")
    chunks_done = models.PositiveIntegerField(default=0, help_text="chunks stored so far")
    peak_rss_kb = models.PositiveBigIntegerField(
        null=True, blank=True, help_text="largest worker peak RSS (KiB) seen by its tasks"
    )
    heartbeat_at = models.DateTimeField(
        null=True, blank=True, help_text="last sign of life of a task working on the run"
    )
    claimed_by = models.CharField(max_length=64, blank=True, help_text="task id of the claim")

    class Meta:
        ordering = ["-created_at"]
        constraints = [
            models.CheckConstraint(condition=Q(progress__lte=100), name="run_progress_le_100"),
        ]

    def __str__(self) -> str:
        return f"Run {self.pk} of {self.comparison.code} ({self.status})"


@receiver(pre_delete, sender=AnalysisRun, dispatch_uid="analysis.lock_run_before_delete")
def lock_run_before_delete(sender: type[AnalysisRun], instance: AnalysisRun, using: str,
                           **kwargs: object) -> None:  # fmt: skip
    """Lock the run row FOR UPDATE before Django's collector deletes its scores.

    ``Score.run`` has no database foreign key; a chunk's transaction holds the run row
    FOR KEY SHARE while it writes scores.  Without this lock a deletion could delete the
    scores (its snapshot not seeing a chunk's uncommitted rows), then wait for the chunk's
    commit and delete the run, leaving that chunk's scores orphaned.  With it, the
    deletion waits for chunks in flight and then sees and deletes their rows, and a chunk
    that starts later waits for the deletion and finds no run (it fails, writes nothing).
    The collector sends ``pre_delete`` inside its transaction before any delete.
    """
    connection = connections[using]
    if connection.vendor == "postgresql":  # SQLite serialises write transactions
        with connection.cursor() as cur:
            cur.execute(
                f"SELECT 1 FROM {sender._meta.db_table} WHERE id = %s FOR UPDATE", [instance.pk]
            )


class AnalysisChunk(models.Model):
    """One chunk of a fanned-out run: the measurement points ``first_point_id`` to
    ``last_point_id`` (those of the comparison with accepted results), analysed by one task.

    ``moments`` keeps per point n, Σx, Σu and M2 (``analysis.core.pooled``): the final
    step pools them into the compatibility matrices without reading the results again.

    A task works on a chunk under a claim: ``token`` (random, new at every claim),
    ``claimed_by`` (the Celery task id) and ``heartbeat_at`` (refreshed while it works).
    Its outputs are stored only if the token is still the chunk's when it saves, under
    the chunk's row lock; a claim is taken over only when its heartbeat is stale or by a
    redelivery of the same task (``analysis.services``).
    """

    run = models.ForeignKey(AnalysisRun, on_delete=models.CASCADE, related_name="chunks")
    index = models.PositiveIntegerField()
    first_point_id = models.BigIntegerField()
    last_point_id = models.BigIntegerField()
    n_results = models.PositiveIntegerField(default=0)
    done = models.BooleanField(default=False)
    attempts = models.PositiveSmallIntegerField(default=0)
    token = models.CharField(max_length=32, blank=True, help_text="the current claim")
    claimed_by = models.CharField(max_length=64, blank=True, help_text="task id of the claim")
    heartbeat_at = models.DateTimeField(null=True, blank=True)
    moments = models.JSONField(default=dict, blank=True)
    peak_rss_kb = models.PositiveBigIntegerField(null=True, blank=True)
    seconds = models.FloatField(null=True, blank=True)
    finished_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["run", "index"]
        constraints = [
            models.UniqueConstraint(fields=["run", "index"], name="chunk_once_per_run"),
        ]

    def __str__(self) -> str:
        return f"chunk {self.index} of run {self.run_id}"


# Stored method names (the core's) that differ from the comparison setting they come from
_SETTING_OF = {"median_made": AssignedValueMethod.MEDIAN}


def method_label(method: str) -> str:
    """A stored method id in words, as the comparison's setting names it
    (``weighted_mean`` → "Weighted mean (largest consistent subset if inconsistent)")."""
    try:
        return str(AssignedValueMethod(_SETTING_OF.get(method, method)).label)
    except ValueError:
        return method.replace("_", " ")


class AssignedValue(models.Model):
    """x_pt and u(x_pt) of one measurement point in one run, and the consistency tests there
    (``analysis.consistency``): one row per point, written with the chunk's scores."""

    run = models.ForeignKey(AnalysisRun, on_delete=models.CASCADE, related_name="assigned_values")
    measurement_point = models.ForeignKey(
        MeasurementPoint, on_delete=models.CASCADE, related_name="assigned_values"
    )
    value = models.FloatField()
    standard_uncertainty = models.FloatField()
    method = models.CharField(max_length=40)
    sigma_pt = models.FloatField(null=True, blank=True)
    coverage_factor = models.FloatField(
        default=2.0,
        help_text="k of U(x_pt) = k·u(x_pt): 2, or the reference laboratory's own k",
    )
    diagnostics = models.JSONField(default=dict, blank=True)
    consistency = models.JSONField(
        default=dict, blank=True,
        help_text="ISO 5725-2 tests at the point (Grubbs, Cochran, Mandel h and k per lab code), "
        "as pt_compare's consistency records without the point keys",
    )  # fmt: skip

    class Meta:
        ordering = ["run", "measurement_point"]
        constraints = [
            models.UniqueConstraint(fields=["run", "measurement_point"], name="assigned_once"),
        ]

    def __str__(self) -> str:
        return f"{self.measurement_point}: {self.value:g} (run {self.run_id})"

    @property
    def method_name(self) -> str:
        return method_label(self.method)

    @property
    def expanded_uncertainty(self) -> float:
        """U(x_pt) = k·u(x_pt)."""
        return self.coverage_factor * self.standard_uncertainty


class Score(models.Model):
    """Scores of one result in one run (ISO 13528 §9); flags as labels."""

    # Bulk-written (a million rows per run): the (run, result) unique index serves lookups
    # by run, so no second index on run; and no database-level foreign keys, whose per-row
    # checks at commit (a FOR KEY SHARE lookup of the referenced row per score) took more
    # time than the COPY itself.  Django still cascades deletes of runs and results to
    # their scores.  Instead, a chunk locks its run row once (FOR KEY SHARE) before writing
    # and deleting a run locks it FOR UPDATE first (``lock_run_before_delete``), so a run
    # cannot be deleted under a chunk; and each chunk checks that every scored result
    # still exists (``analysis.services._save_chunk``).
    run = models.ForeignKey(
        AnalysisRun, on_delete=models.CASCADE, related_name="scores", db_index=False,
        db_constraint=False,
    )  # fmt: skip
    result = models.ForeignKey(
        Result, on_delete=models.CASCADE, related_name="scores", db_constraint=False
    )
    d = models.FloatField()
    # NULL for a phase: a per cent of an angle means nothing (docs/domain.md §12)
    d_percent = models.FloatField(null=True, blank=True)
    en = models.FloatField()
    zeta = models.FloatField()
    z = models.FloatField(null=True, blank=True)
    z_prime = models.FloatField(null=True, blank=True)
    flag = models.CharField(max_length=12, help_text="En flag (the primary score)")
    z_flag = models.CharField(max_length=12, blank=True, help_text="z or z′ flag, if σ_pt set")
    correlation_applied = models.BooleanField(default=False)
    correlation_failed = models.BooleanField(
        default=False,
        help_text="the result is inside the assigned value but u²(x) − u²(x_pt) ≤ 0 (a sole "
        "contributor): ζ and En use the uncorrected sum",
    )
    in_assigned_value = models.BooleanField(
        null=True,
        help_text="the result entered the assigned value (null: the method uses no result, "
        "e.g. a nominal value)",
    )

    class Meta:
        ordering = ["run", "result"]
        constraints = [
            models.UniqueConstraint(fields=["run", "result"], name="score_once"),
        ]

    def __str__(self) -> str:
        return f"En={self.en:.3f} ({self.flag})"


class CompatibilityMatrix(models.Model):
    """Pairwise En between the levels of one factor within one group (docs/domain.md §6)."""

    run = models.ForeignKey(AnalysisRun, on_delete=models.CASCADE, related_name="matrices")
    factor = models.CharField(max_length=12)
    group = models.JSONField(default=dict, help_text="the fixed keys, e.g. device and axis")
    group_key = models.CharField(max_length=300, help_text="canonical text of ``group``")
    levels = models.JSONField(default=list)
    values = models.JSONField(default=list, help_text="aggregated value per level")
    expanded_uncertainties = models.JSONField(default=list)
    en = models.JSONField(default=list, help_text="square matrix, list of rows")
    incompatible_pairs = models.PositiveIntegerField(default=0)

    class Meta:
        ordering = ["run", "factor", "group_key"]
        constraints = [
            models.UniqueConstraint(
                fields=["run", "factor", "group_key"], name="matrix_once_per_group"
            ),
        ]

    def __str__(self) -> str:
        return f"{self.factor} | {self.group_key} (run {self.run_id})"

    def record(self) -> dict:
        """The same shape as ``analysis.pipeline.matrix_record`` (the API answer)."""
        return {
            "factor": self.factor,
            "group": self.group,
            "levels": self.levels,
            "value": self.values,
            "expanded_uncertainty": self.expanded_uncertainties,
            "en": self.en,
            "incompatible_pairs": self.incompatible_pairs,
        }


def report_token() -> str:
    """A random, non-guessable handle for download links (256 bits, URL-safe)."""
    return secrets.token_urlsafe(32)


def report_path(instance: Report, filename: str) -> str:
    """MEDIA_ROOT/reports/<comparison>/<token>.pdf: outside static, not guessable."""
    return f"reports/{instance.comparison.code}/{instance.token}.pdf"


class Report(models.Model):
    """An issued PDF report: summary or one participant's.

    ``version`` counts the files stored for one (comparison, kind, participant); a new
    version supersedes the older ones, which are kept. ``token`` names the file and is
    the only handle of the download URL.
    """

    class Kind(models.TextChoices):
        SUMMARY = "summary", "Summary report"
        PARTICIPANT = "participant", "Participant report"

    class Status(models.TextChoices):
        PRELIMINARY = "preliminary", "Preliminary"
        FINAL = "final", "Final"

    comparison = models.ForeignKey(Comparison, on_delete=models.CASCADE, related_name="reports")
    run = models.ForeignKey(
        AnalysisRun, null=True, blank=True, on_delete=models.PROTECT, related_name="reports"
    )
    kind = models.CharField(max_length=12, choices=Kind.choices)
    participant = models.ForeignKey(
        Participant, null=True, blank=True, on_delete=models.CASCADE, related_name="reports"
    )
    version = models.PositiveIntegerField(default=1)
    token = models.CharField(max_length=64, unique=True, default=report_token, editable=False)
    file = models.FileField(upload_to=report_path, blank=True, max_length=200)
    sha256 = models.CharField(max_length=64, blank=True)
    size = models.PositiveIntegerField(default=0)
    software_version = models.CharField(max_length=40, blank=True)
    superseded = models.BooleanField(default=False)
    #: the status printed in the file, fixed by the comparison's status when it was issued
    #: (final once published): publication supersedes every preliminary one
    status = models.CharField(max_length=12, choices=Status.choices, default=Status.PRELIMINARY)
    created_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["comparison", "kind", "-version"]
        constraints = [
            models.CheckConstraint(
                condition=Q(kind="summary", participant__isnull=True)
                | Q(kind="participant", participant__isnull=False),
                name="report_kind_participant",
            ),
        ]

    def __str__(self) -> str:
        return f"{self.get_kind_display()} v{self.version} ({self.comparison.code})"


class ClaimedJob(models.Model):
    """The fields of a background job claimed by one task at a time (common/jobs.py): the
    claims so far, the current claim's token and task, its heartbeat, and its times."""

    attempts = models.PositiveSmallIntegerField(default=0, help_text="claims so far")
    token = models.CharField(max_length=32, blank=True, help_text="the current claim")
    claimed_by = models.CharField(
        max_length=64, blank=True, help_text="task id of the claim, or of the task last sent"
    )
    heartbeat_at = models.DateTimeField(
        null=True, blank=True, help_text="last sign of life of its task (or when it was sent)"
    )
    created_at = models.DateTimeField(auto_now_add=True)
    started_at = models.DateTimeField(null=True, blank=True)
    finished_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        abstract = True


class ReportBatch(ClaimedJob):
    """A persisted job issuing reports of one run: the summary, or the participant reports
    of a batch of participants (docs/lifecycles.md §4).

    ``pending → running → done | failed``.  The fan-out creates the rows of a run once
    (unique per run, report status, kind and index; a second fan-out finds them), and
    each report task claims its row by the protocol of ``common.jobs``: ``token`` (random,
    new at every claim), ``claimed_by`` (the Celery id of the task holding it, or of the
    task last sent for it) and ``heartbeat_at``.  The stale-job sweep re-queues a row
    pending and not sent, or running and silent, for longer than ``JOB_STALE_SECONDS``.
    The reports themselves stay idempotent by their own rows, so a batch done twice
    issues each report once.
    """

    class Kind(models.TextChoices):
        SUMMARY = "summary", "Summary report"
        PARTICIPANTS = "participants", "Participant reports"

    class Status(models.TextChoices):
        PENDING = "pending", "Pending"
        RUNNING = "running", "Running"
        DONE = "done", "Done"
        FAILED = "failed", "Failed"

    comparison = models.ForeignKey(
        Comparison, on_delete=models.CASCADE, related_name="report_batches"
    )
    run = models.ForeignKey(AnalysisRun, on_delete=models.CASCADE, related_name="report_batches")
    report_status = models.CharField(
        max_length=12, choices=Report.Status.choices,
        help_text="the status of the reports issued: the comparison's when the batch was made",
    )  # fmt: skip
    kind = models.CharField(max_length=12, choices=Kind.choices)
    index = models.PositiveIntegerField(
        default=0, help_text="the batch's place among the run's (participants in code order)"
    )
    participant_ids = models.JSONField(default=list, blank=True)
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.PENDING)
    error = models.TextField(blank=True, help_text="why the last attempt failed")
    report_ids = models.JSONField(default=list, blank=True, help_text="the reports issued")

    class Meta:
        ordering = ["run_id", "report_status", "-kind", "index"]
        constraints = [
            models.UniqueConstraint(
                fields=["run", "report_status", "kind", "index"], name="report_batch_once"
            ),
            models.CheckConstraint(
                condition=Q(kind="participants") | Q(index=0), name="report_batch_one_summary"
            ),
        ]
        indexes = [  # what the sweep reads every minute
            models.Index(
                fields=["status"],
                condition=Q(status__in=["pending", "running"]),
                name="report_batch_active",
            ),
        ]

    def __str__(self) -> str:
        what = "summary" if self.kind == self.Kind.SUMMARY else f"batch {self.index}"
        return f"Reports {what} of run {self.run_id} ({self.status})"


class ReportDownload(models.Model):
    """One download of a report: who (a person, or a laboratory's API key) and when."""

    report = models.ForeignKey(Report, on_delete=models.CASCADE, related_name="downloads")
    user = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )
    laboratory = models.ForeignKey(
        "labs.Laboratory", null=True, blank=True, on_delete=models.SET_NULL
    )
    at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["-at"]

    def __str__(self) -> str:
        return f"{self.report} downloaded at {self.at:%Y-%m-%d %H:%M}"


class Publication(ClaimedJob):
    """A persisted job publishing a comparison's current run (docs/lifecycles.md §1):
    ``pending → running → succeeded | failed``.

    The task renders every final report first (``progress`` and ``stage`` per report),
    and only then, in one transaction, publishes: the status, the final reports stored as
    current, the preliminary ones superseded, the participants' notices.  A failure
    publishes nothing and keeps its ``error``; the comparison stays analysed.  At most one
    publication of a comparison is pending or running.  Claimed, kept alive and re-queued
    by the protocol of ``common.jobs``: ``token`` (random, new at every claim),
    ``claimed_by`` (the Celery id of the task holding it, or of the task last sent) and
    ``heartbeat_at``.
    """

    class Status(models.TextChoices):
        PENDING = "pending", "Pending"
        RUNNING = "running", "Running"
        SUCCEEDED = "succeeded", "Succeeded"
        FAILED = "failed", "Failed"

    comparison = models.ForeignKey(
        Comparison, on_delete=models.CASCADE, related_name="publications"
    )
    run = models.ForeignKey(
        AnalysisRun, on_delete=models.CASCADE, related_name="publications",
        help_text="the current run when publication was asked for: the run published",
    )  # fmt: skip
    requested_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.PENDING)
    progress = models.PositiveSmallIntegerField(default=0)
    stage = models.CharField(max_length=80, blank=True)
    error = models.TextField(blank=True)
    report_ids = models.JSONField(default=list, blank=True, help_text="the final reports issued")

    class Meta:
        ordering = ["-created_at", "-pk"]
        constraints = [
            models.UniqueConstraint(
                fields=["comparison"],
                condition=Q(status__in=["pending", "running"]),
                name="publication_one_active",
            ),
            models.CheckConstraint(
                condition=Q(progress__lte=100), name="publication_progress_le_100"
            ),
        ]

    def __str__(self) -> str:
        return f"Publication {self.pk} of {self.comparison.code} ({self.status})"


def archive_path(instance: RoundArchive, filename: str) -> str:
    """MEDIA_ROOT/archives/<comparison>/<random>.zip: outside static, not guessable."""
    return f"archives/{instance.comparison.code}/{secrets.token_urlsafe(24)}.zip"


class RoundArchive(ClaimedJob):
    """One ZIP of a run's outputs for one audience (docs/interfaces.md §6): the coordinators'
    (``participant`` null) or one participant's.  A persisted job, ``pending → running →
    ready | failed`` (pending is shown as "queued"), claimed, kept alive and re-queued by the
    protocol of ``common.jobs`` (``token``, ``claimed_by``, ``heartbeat_at``), like
    :class:`ReportBatch`.  One row per run and audience: asking again finds it.

    ``file``, ``size`` and ``sha256`` are set together, with ``ready``, once the whole ZIP
    is stored: a row that is not ready has no file.  ``report_ids`` are the reports it
    holds; a report issued for the run since makes a request build it again.
    """

    class Status(models.TextChoices):
        PENDING = "pending", "Queued"
        RUNNING = "running", "Running"
        READY = "ready", "Ready"
        FAILED = "failed", "Failed"

    comparison = models.ForeignKey(Comparison, on_delete=models.CASCADE, related_name="archives")
    run = models.ForeignKey(AnalysisRun, on_delete=models.CASCADE, related_name="archives")
    participant = models.ForeignKey(
        Participant, null=True, blank=True, on_delete=models.CASCADE, related_name="archives",
        help_text="the participant whose archive it is; empty: the coordinators'",
    )  # fmt: skip
    requested_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.PENDING)
    file = models.FileField(upload_to=archive_path, blank=True, max_length=200)
    size = models.PositiveBigIntegerField(default=0)
    sha256 = models.CharField(max_length=64, blank=True)
    report_ids = models.JSONField(default=list, blank=True, help_text="the reports it holds")
    error = models.TextField(blank=True, help_text="why the last attempt failed")

    class Meta:
        ordering = ["run_id", "participant_id"]
        constraints = [
            models.UniqueConstraint(
                fields=["run"], condition=Q(participant__isnull=True),
                name="archive_once_for_coordinators",
            ),
            models.UniqueConstraint(
                fields=["run", "participant"], condition=Q(participant__isnull=False),
                name="archive_once_per_participant",
            ),
            models.CheckConstraint(
                condition=Q(status="ready") | Q(file=""), name="archive_file_only_when_ready"
            ),
        ]  # fmt: skip
        indexes = [  # what the sweep reads every minute
            models.Index(
                fields=["status"],
                condition=Q(status__in=["pending", "running"]),
                name="archive_active",
            ),
        ]

    def __str__(self) -> str:
        who = self.participant.code if self.participant_id and self.participant else "coordinators"
        return f"Archive of run {self.run_id} for {who} ({self.status})"


class KitPointFit(models.Model):
    """Per run and measurement point of a round with kits (docs/domain.md §13, §14): the
    drift judged on each kit's pilot repeats, and for a round of two kits or more the
    least-squares link of every participant to one reference, with its χ² and the
    covariance of the linked degrees of equivalence (``analysis.kit_results.
    covariance_of`` reads it).  Written with the chunk's scores (``analysis.kit_run``)."""

    run = models.ForeignKey(AnalysisRun, on_delete=models.CASCADE, related_name="kit_points")
    measurement_point = models.ForeignKey(
        MeasurementPoint, on_delete=models.CASCADE, related_name="kit_fits"
    )
    reference = models.CharField(
        max_length=16, blank=True, help_text="pilot or weighted_mean; empty: not linked here"
    )
    chi2 = models.FloatField(null=True, blank=True)
    dof = models.IntegerField(null=True, blank=True)
    kit_values = models.JSONField(default=list, blank=True, help_text="kit, value, u per kit")
    drift = models.JSONField(
        default=list, blank=True,
        help_text="per kit: n, model, slope and u(slope) per day, p, t̄, value, u",
    )  # fmt: skip
    unlinked = models.JSONField(
        default=list, blank=True, help_text="codes of the participants not linked to it"
    )
    notes = models.JSONField(default=list, blank=True, help_text="what the run did and why")
    doe_covariance = models.JSONField(
        default=dict, blank=True,
        help_text="the covariance of the linked participants' d, factored: codes, own, factor, "
        "core, cov = diag(own) + factor·core·factorᵀ; empty: not linked",
    )  # fmt: skip

    class Meta:
        ordering = ["run", "measurement_point"]
        constraints = [
            models.UniqueConstraint(fields=["run", "measurement_point"], name="kit_fit_once"),
        ]

    def __str__(self) -> str:
        return f"kits at {self.measurement_point_id} (run {self.run_id})"


class KitScore(models.Model):
    """One result of a round with kits, in one run: the kit it was measured on, its date,
    the drift correction or u_drift applied to it (§13), and its degree of equivalence
    against the linked reference (§14; null where the round has one kit or the
    participant is not linked)."""

    run = models.ForeignKey(AnalysisRun, on_delete=models.CASCADE, related_name="kit_scores")
    result = models.ForeignKey(Result, on_delete=models.CASCADE, related_name="kit_scores")
    kit = models.ForeignKey(
        "proficiency.Kit", null=True, blank=True, on_delete=models.SET_NULL,
        related_name="kit_scores",
    )  # fmt: skip
    measured_on = models.DateField(
        null=True, blank=True,
        help_text="the date its drift was taken at: the stated date, else the midpoint of its "
        "holding of the kit",
    )  # fmt: skip
    drift_correction = models.FloatField(
        default=0.0, help_text="added to the result: −b·(t − t̄) where corrected, else 0"
    )
    u_drift = models.FloatField(
        default=0.0,
        help_text="standard uncertainty added: |t − t̄|·u(b) or u_stab(t), with b·u_t in quadrature",
    )
    linked_d = models.FloatField(null=True, blank=True)
    linked_u = models.FloatField(null=True, blank=True, help_text="u(d)")
    u_link = models.FloatField(null=True, blank=True)

    class Meta:
        ordering = ["run", "result"]
        constraints = [
            models.UniqueConstraint(fields=["run", "result"], name="kit_score_once"),
        ]

    def __str__(self) -> str:
        return f"kit score of {self.result_id} (run {self.run_id})"

    @property
    def linked_expanded_uncertainty(self) -> float | None:
        """U(d) = 2·u(d) (docs/domain.md §6)."""
        return None if self.linked_u is None else 2.0 * self.linked_u
