"""Laboratories, their people, their participation in comparisons and their results."""

from __future__ import annotations

from django.conf import settings
from django.db import models
from django.db.models import F, Q
from django.db.models.functions import NullIf
from rest_framework_api_key.models import AbstractAPIKey

from proficiency.models import Comparison, MeasurementPoint, finite_positive


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
    note = models.CharField(max_length=500, blank=True)

    class Meta:
        ordering = ["submission", "measurement_point"]
        constraints = [
            models.UniqueConstraint(
                fields=["submission", "measurement_point"], name="result_one_per_point"
            ),
            models.CheckConstraint(condition=finite_positive("value"), name="result_value_pos"),
            models.CheckConstraint(
                condition=finite_positive("expanded_uncertainty"), name="result_U_pos"
            ),
            models.CheckConstraint(
                condition=finite_positive("coverage_factor"), name="result_k_pos"
            ),
            models.CheckConstraint(
                condition=Q(dof__isnull=True) | Q(dof__gt=0), name="result_dof_pos"
            ),
        ]

    def __str__(self) -> str:
        return f"{self.measurement_point}: {self.value:g} ± {self.expanded_uncertainty:g}"


class LabAPIKey(AbstractAPIKey):
    """A hashed, revocable API key that belongs to one laboratory (formats.md §3).

    Only the prefix and the hash are stored; the key itself is shown once, when it
    is created (``labs.services.api_key_create``)."""

    laboratory = models.ForeignKey(Laboratory, on_delete=models.CASCADE, related_name="api_keys")
    created_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )

    class Meta(AbstractAPIKey.Meta):
        verbose_name = "lab API key"
        verbose_name_plural = "lab API keys"
