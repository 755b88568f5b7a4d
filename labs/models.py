"""Laboratories, their people, their participation in comparisons and their results."""

from __future__ import annotations

from typing import ClassVar

from django.conf import settings
from django.db import models
from django.db.models import F, Q
from django.db.models.functions import NullIf
from rest_framework_api_key.models import AbstractAPIKey, APIKeyManager

from common import quantities
from common.rows import JoinedQuery, ModelColumns
from labs.importers.schema import ENTERED_MAX_CHARS
from proficiency.models import (
    FLOAT_MAX,
    Comparison,
    Device,
    MeasurementPoint,
    finite_positive,
)


class Laboratory(models.Model):
    name = models.CharField(max_length=200, unique=True)
    country = models.CharField(max_length=2, blank=True, help_text="ISO 3166-1 alpha-2 code")
    accreditation_body = models.CharField(max_length=100, blank=True)
    accreditation_number = models.CharField(max_length=60, blank=True)
    contact_name = models.CharField(max_length=120, blank=True)
    contact_email = models.EmailField(blank=True)
    created_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["name"]
        verbose_name_plural = "laboratories"

    def __str__(self) -> str:
        return self.name


class Membership(models.Model):
    class Role(models.TextChoices):
        STAFF = "staff", "Staff"
        MANAGER = "manager", "Manager"

    user = models.ForeignKey(
        settings.AUTH_USER_MODEL, on_delete=models.CASCADE, related_name="memberships"
    )
    laboratory = models.ForeignKey(Laboratory, on_delete=models.CASCADE, related_name="members")
    role = models.CharField(max_length=10, choices=Role.choices, default=Role.STAFF)

    class Meta:
        ordering = ["laboratory", "user"]
        constraints = [
            models.UniqueConstraint(fields=["user", "laboratory"], name="membership_unique"),
        ]

    def __str__(self) -> str:
        return f"{self.user} @ {self.laboratory} ({self.role})"


class Participant(models.Model):
    """A laboratory taking part in one comparison, known to the others only by ``code``.

    The code is drawn at random (``labs.services.participant_code_new``), never
    derived from the laboratory, and differs between comparisons.
    """

    comparison = models.ForeignKey(
        Comparison, on_delete=models.CASCADE, related_name="participants"
    )
    laboratory = models.ForeignKey(
        Laboratory, on_delete=models.PROTECT, related_name="participations"
    )
    code = models.CharField(max_length=8)
    is_reference = models.BooleanField(
        default=False, help_text="Pilot / reference laboratory of the comparison."
    )
    invited_at = models.DateTimeField(auto_now_add=True)
    # The participant's scope (docs/domain.md §10): the points it measures are those whose
    # device, bench, axis and frequency are each in its list; an empty list allows every
    # value, so a participant with no scope measures every point of the comparison.
    scope_devices = models.ManyToManyField(
        Device, blank=True, related_name="scoped_participants",
        help_text="Devices the laboratory measures (none chosen: every device).",
    )  # fmt: skip
    scope_benches = models.JSONField(
        default=list, blank=True, help_text="Benches the laboratory measures ([]: every bench)."
    )
    scope_axes = models.JSONField(
        default=list, blank=True, help_text="Axes the laboratory measures ([]: every axis)."
    )
    scope_frequencies_hz = models.JSONField(
        default=list, blank=True,
        help_text="Frequencies the laboratory measures, Hz ([]: every frequency).",
    )  # fmt: skip

    class Meta:
        ordering = ["comparison", "code"]
        constraints = [
            models.UniqueConstraint(fields=["comparison", "laboratory"], name="participant_once"),
            models.UniqueConstraint(fields=["comparison", "code"], name="participant_code_unique"),
        ]

    def __str__(self) -> str:
        return f"{self.code} ({self.comparison.code})"


class Submission(models.Model):
    """One version of a participant's results. A correction is a new version."""

    class Status(models.TextChoices):
        DRAFT = "draft", "Draft"
        SUBMITTED = "submitted", "Submitted"
        ACCEPTED = "accepted", "Accepted"
        REJECTED = "rejected", "Rejected"

    class Source(models.TextChoices):
        WEB = "web", "Web form"
        FILE = "file", "File upload"
        API = "api", "REST API"

    participant = models.ForeignKey(
        Participant, on_delete=models.CASCADE, related_name="submissions"
    )
    version = models.PositiveIntegerField()
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.DRAFT)
    source = models.CharField(max_length=5, choices=Source.choices, default=Source.WEB)
    submitted_by = models.ForeignKey(
        settings.AUTH_USER_MODEL,
        null=True,
        blank=True,
        on_delete=models.SET_NULL,
        related_name="submissions",
    )
    message = models.TextField(blank=True, help_text="Coordinator's message on the decision.")
    created_at = models.DateTimeField(auto_now_add=True)
    submitted_at = models.DateTimeField(null=True, blank=True)
    decided_at = models.DateTimeField(null=True, blank=True)
    #: SHA-256 of the stored results (point, value, unit, U, k, dof, note by point): an
    #: identical submission sent again shortly after answers this version
    content_sha256 = models.CharField(max_length=64, blank=True)

    class Meta:
        ordering = ["participant", "-version"]
        constraints = [
            models.UniqueConstraint(fields=["participant", "version"], name="submission_version"),
            models.CheckConstraint(condition=Q(version__gte=1), name="submission_version_pos"),
            models.CheckConstraint(
                condition=Q(status__in=["draft", "submitted", "accepted", "rejected"]),
                name="submission_status_valid",
            ),
        ]

    def __str__(self) -> str:
        return f"{self.participant} v{self.version} ({self.status})"


class SubmissionKey(models.Model):
    """An ``Idempotency-Key`` a participant sent with a submission request, kept for
    ``IDEMPOTENCY_KEY_HOURS``: the same key with the same content answers ``submission``
    again; with other content it is refused (422)."""

    participant = models.ForeignKey(
        Participant, on_delete=models.CASCADE, related_name="submission_keys"
    )
    key = models.CharField(max_length=255)
    #: SHA-256 of what was asked: the results' content and the submit flag
    fingerprint = models.CharField(max_length=64)
    submission = models.ForeignKey(
        Submission, on_delete=models.CASCADE, related_name="request_keys"
    )
    created_at = models.DateTimeField(auto_now_add=True, db_index=True)

    class Meta:
        constraints = [
            models.UniqueConstraint(fields=["participant", "key"], name="submission_key_unique")
        ]

    def __str__(self) -> str:
        return f"{self.participant} key {self.key[:12]}"


class Result(models.Model):
    """One reported value for one measurement point, with expanded uncertainty U and k."""

    submission = models.ForeignKey(Submission, on_delete=models.CASCADE, related_name="results")
    measurement_point = models.ForeignKey(
        MeasurementPoint, on_delete=models.PROTECT, related_name="results"
    )
    value = models.FloatField()
    unit = models.CharField(max_length=20)
    expanded_uncertainty = models.FloatField()
    coverage_factor = models.FloatField(default=2.0)
    standard_uncertainty = models.GeneratedField(
        # NULLIF keeps k = 0 from raising a division error before the k > 0 check refuses it.
        expression=F("expanded_uncertainty") / NullIf(F("coverage_factor"), 0.0),
        output_field=models.FloatField(),
        db_persist=True,
    )
    dof = models.FloatField(null=True, blank=True, help_text="Effective degrees of freedom")
    repeat_sd = models.FloatField(
        null=True, blank=True,
        help_text="Within-laboratory standard deviation of the repeats behind the value (their "
        "mean), in the value's unit",
    )  # fmt: skip
    n_repeats = models.PositiveIntegerField(
        null=True, blank=True, help_text="Number of repeats behind repeat_sd (>= 2)"
    )
    note = models.CharField(max_length=500, blank=True)
    expanded_uncertainty_entered = models.CharField(
        max_length=ENTERED_MAX_CHARS, blank=True, default="", db_default="",
        help_text="U as the laboratory wrote it when it gave it relative (\"1.2 %\"); blank when "
        "it gave the absolute number. expanded_uncertainty holds the absolute value either way",
    )  # fmt: skip
    measured_on = models.DateField(
        null=True, blank=True,
        help_text="The date the laboratory states it measured the value; null: not stated "
        "(a kit's drift is then taken over its holding of the kit)",
    )  # fmt: skip

    class Meta:
        ordering = ["submission", "measurement_point"]
        constraints = [
            models.UniqueConstraint(
                fields=["submission", "measurement_point"], name="result_one_per_point"
            ),
            # > 0 for a magnitude, any finite number for a phase (the importers check the
            # point's quantity kind, docs/interfaces.md §1); finite here for every kind
            models.CheckConstraint(
                condition=Q(value__gte=-FLOAT_MAX) & Q(value__lte=FLOAT_MAX),
                name="result_value_finite",
            ),
            models.CheckConstraint(
                condition=finite_positive("expanded_uncertainty"), name="result_U_pos"
            ),
            models.CheckConstraint(
                condition=finite_positive("coverage_factor"), name="result_k_pos"
            ),
            models.CheckConstraint(
                condition=Q(dof__isnull=True) | Q(dof__gt=0), name="result_dof_pos"
            ),
            models.CheckConstraint(
                condition=Q(repeat_sd__isnull=True, n_repeats__isnull=True)
                | (finite_positive("repeat_sd") & Q(n_repeats__gte=2)),
                name="result_repeats_paired",
            ),
        ]

    def __str__(self) -> str:
        return f"{self.measurement_point}: {self.value:g} ± {self.expanded_uncertainty:g}"


class LabAPIKeyManager(APIKeyManager):
    _usable_by_prefix: JoinedQuery | None = None

    def get_usable_keys(self) -> models.QuerySet[LabAPIKey]:
        """The authentication lookup fetches the key's laboratory in the same query: every
        API request reads it (scope, throttling), so this saves one query per request."""
        return super().get_usable_keys().select_related("laboratory")

    def get_from_key(self, key: str) -> LabAPIKey:
        """The library's lookup (a usable, i.e. not revoked, key with this prefix whose hash
        matches; ``DoesNotExist`` otherwise), read from the database at every call as
        before, with its laboratory, in one SQL statement written once
        (:mod:`common.rows`) instead of one compiled by the ORM per request."""
        prefix = key.partition(".")[0]
        if LabAPIKeyManager._usable_by_prefix is None:
            LabAPIKeyManager._usable_by_prefix = JoinedQuery(
                [ModelColumns(LabAPIKey, "k"), ModelColumns(Laboratory, "l")],
                'FROM "labs_labapikey" "k" INNER JOIN "labs_laboratory" "l" '
                'ON "l"."id" = "k"."laboratory_id" WHERE "k"."prefix" = %s AND "k"."revoked" = %s',
            )
        rows = LabAPIKeyManager._usable_by_prefix.fetch([prefix, False], using=self.db)
        if not rows:
            raise LabAPIKey.DoesNotExist("LabAPIKey matching query does not exist.")
        api_key, laboratory = rows[0]
        api_key.laboratory = laboratory  # type: ignore[attr-defined]
        if not api_key.is_valid(key):  # type: ignore[attr-defined]
            raise LabAPIKey.DoesNotExist("Key is not valid.")
        return api_key  # type: ignore[return-value]


class LabAPIKey(AbstractAPIKey):
    """A hashed, revocable API key that belongs to one laboratory (docs/interfaces.md §3).

    Only the prefix and the hash are stored; the key itself is shown once, when it
    is created (``labs.services.api_key_create``)."""

    objects: ClassVar[LabAPIKeyManager] = LabAPIKeyManager()
    laboratory = models.ForeignKey(Laboratory, on_delete=models.CASCADE, related_name="api_keys")
    created_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )

    class Meta(AbstractAPIKey.Meta):
        verbose_name = "lab API key"
        verbose_name_plural = "lab API keys"


# --- raw time series behind a result (docs/interfaces.md §2) ----------------------


def raw_file_path(instance: RawFile, filename: str) -> str:
    """Content-addressed: ``raw/ab/abcdef…`` (the name the lab gave is kept on the record)."""
    return f"raw/{instance.sha256[:2]}/{instance.sha256}"


class RawFile(models.Model):
    """The bytes of one uploaded raw file, stored once per SHA-256 and never modified."""

    sha256 = models.CharField(max_length=64, unique=True)
    file = models.FileField(upload_to=raw_file_path, max_length=200)
    size = models.PositiveBigIntegerField()
    created_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["-created_at"]

    def __str__(self) -> str:
        return f"{self.sha256[:12]}… ({self.size} B)"


class RawRecord(models.Model):
    """Raw record(s) attached by a laboratory to a measurement point of its submission:
    the MEMS record, an optional reference record (``ref``/``encoder_rad``), and the
    metadata of each (sidecar merged with the form fields, docs/interfaces.md §2)."""

    participant = models.ForeignKey(
        Participant, on_delete=models.CASCADE, related_name="raw_records"
    )
    submission = models.ForeignKey(Submission, on_delete=models.CASCADE, related_name="raw_records")
    measurement_point = models.ForeignKey(
        MeasurementPoint, on_delete=models.PROTECT, related_name="raw_records"
    )
    data_file = models.ForeignKey(RawFile, on_delete=models.PROTECT, related_name="records")
    data_name = models.CharField(max_length=255, help_text="File name as uploaded.")
    metadata = models.JSONField(default=dict)
    reference_file = models.ForeignKey(
        RawFile,
        null=True,
        blank=True,
        on_delete=models.PROTECT,
        related_name="reference_records",
    )
    reference_name = models.CharField(max_length=255, blank=True)
    reference_metadata = models.JSONField(default=dict, blank=True)
    uploaded_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )
    created_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["participant", "-created_at"]
        constraints = [
            models.CheckConstraint(
                condition=Q(reference_file__isnull=True) | ~Q(reference_name=""),
                name="rawrecord_reference_named",
            ),
        ]

    def __str__(self) -> str:
        return f"{self.data_name} → {self.measurement_point_id} ({self.participant})"


class RawRecomputation(models.Model):
    """The service's recomputation of one raw record (``pending → running → succeeded |
    failed``); one per record, so a task delivered twice cannot store two results.

    Lost workers: the claim (``claimed_by``, the Celery task id, and ``started_at``) and
    the heartbeat follow the analysis runs' protocol (``common.jobs``): a row silent
    for ``JOB_STALE_SECONDS`` is re-queued by the sweep and may be taken over.

    ``axes`` holds every axis of the record (``pt_sensitivity --format json``); the
    ``sensitivity`` columns are the figure of the measurement point's quantity kind (its
    axis's magnitude or phase, or gyroscope axis G<axis>: docs/lifecycles.md §5).  ``en``
    compares the reported and the recomputed value: D / √(U_rep² + U_rec²), D = S_rep −
    S_rec, wrapped into (−180°, 180°] for a phase."""

    class Status(models.TextChoices):
        PENDING = "pending", "Pending"
        RUNNING = "running", "Running"
        SUCCEEDED = "succeeded", "Succeeded"
        FAILED = "failed", "Failed"

    record = models.OneToOneField(RawRecord, on_delete=models.CASCADE, related_name="recomputation")
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.PENDING)
    error = models.TextField(blank=True)
    method = models.CharField(max_length=20, default="sine-fit")
    software_version = models.CharField(max_length=40)
    parameters = models.JSONField(default=dict)
    fs_hz = models.FloatField(null=True, blank=True)
    u_fs_hz = models.FloatField(null=True, blank=True)
    axes = models.JSONField(default=list, blank=True)
    sensitivity = models.FloatField(null=True, blank=True)
    standard_uncertainty = models.FloatField(null=True, blank=True)
    expanded_uncertainty = models.FloatField(null=True, blank=True)
    coverage_factor = models.FloatField(null=True, blank=True)
    budget = models.JSONField(default=list, blank=True)
    reported_value = models.FloatField()
    reported_expanded_uncertainty = models.FloatField()
    reported_coverage_factor = models.FloatField()
    en = models.FloatField(null=True, blank=True)
    created_at = models.DateTimeField(auto_now_add=True)
    started_at = models.DateTimeField(null=True, blank=True)
    finished_at = models.DateTimeField(null=True, blank=True)
    heartbeat_at = models.DateTimeField(
        null=True, blank=True, help_text="last sign of life of the task working on it"
    )
    claimed_by = models.CharField(max_length=64, blank=True, help_text="task id of the claim")

    class Meta:
        ordering = ["-created_at"]
        constraints = [
            models.CheckConstraint(
                condition=Q(status__in=["pending", "running", "succeeded", "failed"]),
                name="rawrecomp_status_valid",
            ),
            models.CheckConstraint(
                condition=~Q(status="succeeded") | Q(sensitivity__isnull=False),
                name="rawrecomp_succeeded_has_value",
            ),
        ]

    def __str__(self) -> str:
        return f"recomputation of {self.record_id} ({self.status})"

    @property
    def reported_standard_uncertainty(self) -> float:
        return self.reported_expanded_uncertainty / self.reported_coverage_factor

    @property
    def circular(self) -> bool:
        """The point's kind is on the circle (a phase, ``common.quantities``)."""
        return quantities.is_circular(self.record.measurement_point.quantity)

    @property
    def relative_difference(self) -> float | None:
        """(S_rec − S_rep) / S_rep in %; None for a phase (see :attr:`phase_difference`)."""
        if self.sensitivity is None or self.circular:
            return None
        return 100 * (self.sensitivity - self.reported_value) / self.reported_value

    @property
    def phase_difference(self) -> float | None:
        """For a phase point, D = φ_rep − φ_rec wrapped into (−180°, 180°] (docs/domain.md
        §12), the difference En divides; None for another kind."""
        if self.sensitivity is None or not self.circular:
            return None
        return quantities.wrap_degrees(self.reported_value - self.sensitivity)


class Notice(models.Model):
    """A message to one laboratory about one comparison (docs/lifecycles.md §6): shown in
    the laboratory's inbox and e-mailed to its members once, after commit.

    ``dedupe_key`` names the event (e.g. ``receipt:<submission id>``): the same event never
    makes a second notice, so a service or a beat run repeated changes nothing.
    """

    class Kind(models.TextChoices):
        INVITATION = "invitation", "Invitation"
        OPENED = "opened", "Round opened"
        REMINDER = "reminder", "Deadline reminder"
        RECEIPT = "receipt", "Submission receipt"
        ACCEPTED = "accepted", "Submission accepted"
        REJECTED = "rejected", "Submission rejected"
        CHECK = "check", "Request to check a result"
        PUBLISHED = "published", "Results published"
        APPLIED = "applied", "Application received"
        DECLINED = "declined", "Application declined"

    laboratory = models.ForeignKey(Laboratory, on_delete=models.CASCADE, related_name="notices")
    comparison = models.ForeignKey(Comparison, on_delete=models.CASCADE, related_name="notices")
    participant = models.ForeignKey(
        Participant, null=True, blank=True, on_delete=models.CASCADE, related_name="notices"
    )
    kind = models.CharField(max_length=12, choices=Kind.choices)
    subject = models.CharField(max_length=200)
    body = models.TextField()
    #: the site path of the page the notice concerns (``SITE_URL`` makes it absolute)
    link = models.CharField(max_length=500, blank=True)
    dedupe_key = models.CharField(max_length=200, unique=True)
    created_at = models.DateTimeField(auto_now_add=True, db_index=True)
    read_at = models.DateTimeField(null=True, blank=True)
    emailed_at = models.DateTimeField(null=True, blank=True)
    #: the addresses the e-mail went to (comma-separated), for the coordinator's list
    emailed_to = models.TextField(blank=True)

    class Meta:
        ordering = ["-created_at", "-id"]
        indexes = [models.Index(fields=["laboratory", "read_at"], name="notice_lab_unread")]
        constraints = [
            models.CheckConstraint(
                condition=Q(
                    kind__in=[
                        "invitation", "opened", "reminder", "receipt", "accepted",
                        "rejected", "check", "published", "applied", "declined",
                    ]
                ),
                name="notice_kind_valid",
            ),
        ]  # fmt: skip

    def __str__(self) -> str:
        return f"{self.kind} to {self.laboratory} ({self.comparison})"


class Enrolment(models.Model):
    """A laboratory's application to take part in a round whose call is open, with the scope
    it asks for (docs/lifecycles.md §7). Accepting it invites the laboratory as a
    coordinator's invitation does: a random participant code, the requested (or amended)
    scope and the invitation notice; the application keeps the participant it made.

    At most one application per laboratory and round is pending or accepted; a declined or
    withdrawn one stays as history and the laboratory may apply again.
    """

    class Status(models.TextChoices):
        PENDING = "pending", "Pending"
        ACCEPTED = "accepted", "Accepted"
        DECLINED = "declined", "Declined"
        WITHDRAWN = "withdrawn", "Withdrawn"

    laboratory = models.ForeignKey(Laboratory, on_delete=models.CASCADE, related_name="enrolments")
    comparison = models.ForeignKey(Comparison, on_delete=models.CASCADE, related_name="enrolments")
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.PENDING)
    # the requested scope, the shape of Participant's (docs/domain.md §10): empty lists allow
    # every value
    scope_devices = models.ManyToManyField(Device, blank=True, related_name="enrolments")
    scope_benches = models.JSONField(default=list, blank=True)
    scope_axes = models.JSONField(default=list, blank=True)
    scope_frequencies_hz = models.JSONField(default=list, blank=True)
    note = models.TextField(blank=True, help_text="The laboratory's note to the coordinator.")
    reason = models.TextField(blank=True, help_text="The coordinator's reason for declining.")
    applied_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL,
        related_name="enrolments_applied", help_text="Empty when applied with an API key.",
    )  # fmt: skip
    decided_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL,
        related_name="enrolments_decided",
    )  # fmt: skip
    participant = models.OneToOneField(
        Participant, null=True, blank=True, on_delete=models.SET_NULL, related_name="enrolment"
    )
    created_at = models.DateTimeField(auto_now_add=True)
    decided_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["comparison", "-created_at", "-id"]
        constraints = [
            models.UniqueConstraint(
                fields=["laboratory", "comparison"],
                condition=Q(status__in=["pending", "accepted"]),
                name="enrolment_one_live",
            ),
            models.CheckConstraint(
                condition=Q(status__in=["pending", "accepted", "declined", "withdrawn"]),
                name="enrolment_status_valid",
            ),
        ]

    def __str__(self) -> str:
        return f"{self.laboratory} → {self.comparison} ({self.status})"


class KitSlot(models.Model):
    """A participant's turn with a kit (docs/domain.md §15): the ``position``-th holder of
    the kit in its loop, from ``starts_on`` to ``ends_on``. The pilot has several slots
    on every kit (before, between, after); a linking laboratory has slots on two kits."""

    kit = models.ForeignKey("proficiency.Kit", on_delete=models.CASCADE, related_name="slots")
    participant = models.ForeignKey(Participant, on_delete=models.CASCADE, related_name="kit_slots")
    position = models.PositiveIntegerField()
    starts_on = models.DateField()
    ends_on = models.DateField()

    class Meta:
        ordering = ["kit", "position"]
        constraints = [
            models.UniqueConstraint(fields=["kit", "position"], name="kit_slot_position"),
            models.CheckConstraint(
                condition=Q(ends_on__gte=models.F("starts_on")), name="kit_slot_dates"
            ),
        ]

    def __str__(self) -> str:
        return f"{self.kit} #{self.position}: {self.participant.code}"


class Handover(models.Model):
    """A kit passing from one holder to the next: dispatched by the sender, received by the
    receiver with the condition it arrived in. ``from_slot`` None: sent by the provider;
    ``to_slot`` None: returned to the provider."""

    class Condition(models.TextChoices):
        GOOD = "good", "Complete and undamaged"
        DAMAGED = "damaged", "Damaged"
        INCOMPLETE = "incomplete", "Incomplete"

    kit = models.ForeignKey("proficiency.Kit", on_delete=models.CASCADE, related_name="handovers")
    from_slot = models.ForeignKey(
        KitSlot, null=True, blank=True, on_delete=models.CASCADE, related_name="sent"
    )
    to_slot = models.ForeignKey(
        KitSlot, null=True, blank=True, on_delete=models.CASCADE, related_name="received"
    )
    dispatched_at = models.DateTimeField()
    dispatched_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL,
        related_name="kits_dispatched",
    )  # fmt: skip
    carrier_note = models.CharField(max_length=500, blank=True, help_text="Carrier, tracking.")
    received_at = models.DateTimeField(null=True, blank=True)
    received_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL,
        related_name="kits_received",
    )  # fmt: skip
    condition = models.CharField(max_length=10, choices=Condition.choices, blank=True)
    condition_note = models.CharField(max_length=1000, blank=True)
    photo = models.FileField(upload_to="handovers/%Y/", blank=True)

    class Meta:
        ordering = ["kit", "dispatched_at", "pk"]
        constraints = [
            models.UniqueConstraint(
                fields=["to_slot"],
                condition=Q(to_slot__isnull=False),
                name="handover_one_arrival",
            ),
            models.UniqueConstraint(
                fields=["from_slot"],
                condition=Q(from_slot__isnull=False),
                name="handover_one_departure",
            ),
            models.CheckConstraint(
                condition=Q(received_at__isnull=True) | ~Q(condition=""),
                name="handover_received_condition",
            ),
            models.CheckConstraint(
                condition=Q(condition__in=["", "good", "damaged", "incomplete"]),
                name="handover_condition_valid",
            ),
        ]

    def __str__(self) -> str:
        return f"{self.kit}: {self.from_slot_id or 'provider'} → {self.to_slot_id or 'provider'}"


class KitMeasurement(models.Model):
    """A measurement of one kit at one point on one date (docs/domain.md §13–§15): without
    a participant, the pilot's repeat over the circulation from which the kit's drift is
    judged (U for a change over time); with one, that linking laboratory's measurement of
    a kit of its other loop (its full U), which links the two loops."""

    kit = models.ForeignKey(
        "proficiency.Kit", on_delete=models.CASCADE, related_name="measurements"
    )
    measurement_point = models.ForeignKey(
        "proficiency.MeasurementPoint", on_delete=models.CASCADE, related_name="kit_measurements"
    )
    participant = models.ForeignKey(
        Participant, null=True, blank=True, on_delete=models.CASCADE,
        related_name="kit_measurements",
        help_text="the linking laboratory that measured it; empty: the pilot's repeat",
    )  # fmt: skip
    measured_on = models.DateField()
    value = models.FloatField()
    expanded_uncertainty = models.FloatField(
        help_text="the pilot's repeat: U for a change over time (its reproducibility); a "
        "laboratory's: its full U; k as given"
    )
    coverage_factor = models.FloatField(default=2.0)

    class Meta:
        ordering = ["kit", "measurement_point", "measured_on"]
        constraints = [
            models.UniqueConstraint(
                fields=["kit", "measurement_point", "measured_on"],
                condition=Q(participant__isnull=True),
                name="kit_measurement_once",
            ),
            models.UniqueConstraint(
                fields=["kit", "measurement_point", "measured_on", "participant"],
                name="kit_measurement_lab_once",
            ),
            models.CheckConstraint(
                condition=Q(expanded_uncertainty__gt=0) & Q(coverage_factor__gt=0),
                name="kit_measurement_u_pos",
            ),
        ]

    def __str__(self) -> str:
        return f"{self.kit} {self.measurement_point_id} on {self.measured_on}: {self.value:g}"
