"""The comparison domain: rounds, artefacts (devices), measurement points, reference values."""

from __future__ import annotations

import sys

from django.conf import settings
from django.core.exceptions import ValidationError
from django.db import models
from django.db.models import Q

from common import quantities
from common.points import PointKey, point_label
from proficiency import protocols

#: What a comparison code may contain, in the words of the error (form and API alike)
CODE_INVALID = (
    "A comparison code may contain only letters, digits, hyphens and underscores "
    "(no spaces), for example IMU-2024-01."
)
FLOAT_MAX = sys.float_info.max  # "finite" in a CHECK constraint: NaN and ±inf both fail <= max


def finite_positive(field: str) -> Q:
    """CHECK condition: 0 < field <= largest float (rejects 0, negatives, NaN and inf)."""
    return Q(**{f"{field}__gt": 0}) & Q(**{f"{field}__lte": FLOAT_MAX})


class ComparisonStatus(models.TextChoices):
    DRAFT = "draft", "Draft"
    OPEN = "open", "Open for submissions"
    CLOSED = "closed", "Closed"
    ANALYSED = "analysed", "Analysed"
    PUBLISHED = "published", "Published"


class AssignedValueMethod(models.TextChoices):
    """docs/domain.md §5."""

    REFERENCE = "reference", "Reference laboratory (pilot)"
    NOMINAL = "nominal", "Nominal value with tolerance"
    WEIGHTED_MEAN = "weighted_mean", "Weighted mean (largest consistent subset if inconsistent)"
    ALGORITHM_A = "algorithm_a", "Robust consensus (ISO 13528 Algorithm A)"
    MEDIAN = "median", "Median with MADe"
    MEDIAN_NIQR = "median_niqr", "Median with nIQR"
    Q_HAMPEL = "q_hampel", "Q/Hampel (ISO 13528 Q method and Hampel estimator)"
    DERSIMONIAN_LAIRD = "dersimonian_laird", "Random effects (DerSimonian–Laird)"


class SigmaPtMode(models.TextChoices):
    NONE = "none", "Not used (En and ζ only)"
    ABSOLUTE = "absolute", "Prescribed, absolute"
    RELATIVE = "relative", "Prescribed, relative to the assigned value (%)"
    ROBUST = "robust", "Robust s* of the round"


class DriftTreatment(models.TextChoices):
    """What a run does where the pilot's repeats show a kit drifting (docs/domain.md §13)."""

    CORRECT = "correct", "Correct the reference to each participant's date"
    U_STAB = "u_stab", "Keep the constant value and add u_stab for each participant"


class Distribution(models.TextChoices):
    RECTANGULAR = "rectangular", "Rectangular"
    NORMAL = "normal", "Normal (tolerance is an expanded uncertainty, k = 2)"
    TRIANGULAR = "triangular", "Triangular"


class Axis(models.TextChoices):
    X = "X", "X"
    Y = "Y", "Y"
    Z = "Z", "Z"


class Bench(models.TextChoices):
    LINEAR = protocols.LINEAR, "Linear"
    CURVILINEAR = protocols.CURVILINEAR, "Curvilinear"
    SINE_ON_RANDOM = protocols.SINE_ON_RANDOM, "Sine-on-random"


class Direction(models.TextChoices):
    VERTICAL = "vertical", "Vertical"
    TANGENTIAL = "tangential", "Tangential"
    RADIAL = "radial", "Radial"


DEFAULT_UNIT = "D/(m/s^2)"

#: Days before the deadline on which participants that have not submitted are reminded
#: (docs/lifecycles.md §6); a new comparison's default, and that of every existing one.
DEFAULT_REMINDER_DAYS = "7,1"
MAX_REMINDER_DAYS = 365


def reminder_days_parse(text: str) -> list[int]:
    """``"7, 1"`` → ``[1, 7]`` (ascending, no repeats); ``ValueError`` naming the bad item."""
    days: set[int] = set()
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        if not (item.isascii() and item.isdigit()) or not 1 <= int(item) <= MAX_REMINDER_DAYS:
            raise ValueError(
                f"{item!r} is not a number of days from 1 to {MAX_REMINDER_DAYS}; write whole "
                "days separated by commas, e.g. 7,1 (empty: no reminders)."
            )
        days.add(int(item))
    return sorted(days)


def validate_reminder_days(text: str) -> None:
    try:
        reminder_days_parse(text)
    except ValueError as exc:
        raise ValidationError(str(exc)) from None


class Comparison(models.Model):
    """One proficiency test / interlaboratory comparison round."""

    code = models.SlugField(max_length=40, unique=True, help_text="e.g. IMU-2024-01")
    title = models.CharField(max_length=200)
    description = models.TextField(blank=True)
    protocol = models.CharField(
        max_length=40, choices=protocols.PROTOCOL_CHOICES, default=protocols.CUSTOM
    )
    status = models.CharField(
        max_length=12, choices=ComparisonStatus.choices, default=ComparisonStatus.DRAFT
    )
    submission_deadline = models.DateTimeField(null=True, blank=True)
    assigned_value_method = models.CharField(
        max_length=24, choices=AssignedValueMethod.choices, default=AssignedValueMethod.REFERENCE
    )
    sigma_pt_mode = models.CharField(
        max_length=12, choices=SigmaPtMode.choices, default=SigmaPtMode.NONE
    )
    sigma_pt_value = models.FloatField(
        null=True, blank=True, help_text="Absolute value, or percent for the relative mode."
    )
    en_limit = models.FloatField(default=1.0)
    drift_treatment = models.CharField(
        max_length=8, choices=DriftTreatment.choices, default=DriftTreatment.CORRECT,
        help_text="Where the pilot's repeats show a kit drifting (a significant slope): correct "
        "for it, or add its u_stab at each participant's date.",
    )  # fmt: skip
    reminder_days = models.CharField(
        max_length=60,
        blank=True,
        default=DEFAULT_REMINDER_DAYS,
        validators=[validate_reminder_days],
        help_text="Days before the deadline on which laboratories that have not submitted "
        "are reminded, e.g. 7,1 (empty: no reminders).",
    )
    coordinators = models.ManyToManyField(
        settings.AUTH_USER_MODEL, blank=True, related_name="coordinated_comparisons"
    )
    # The round's call for participation (docs/lifecycles.md §7): laboratories may apply
    # while it is open (proficiency.services.enrolment_check says when).
    enrolment_open = models.BooleanField(
        default=False,
        help_text="Laboratories may apply to take part (listed under Open calls) while the "
        "round is draft or open, before the enrolment closes and before the deadline.",
    )
    enrolment_closes = models.DateTimeField(
        null=True, blank=True, help_text="Applications are taken until then (empty: until the "
        "submission deadline).",
    )  # fmt: skip
    # Printed in the reports (docs/domain.md §9); edited by the coordinators, audit-logged.
    report_comments = models.TextField(
        blank=True, help_text="Comments on performance and advice on interpretation."
    )
    report_conclusions = models.TextField(blank=True)
    authorised_by_name = models.CharField(
        max_length=120, blank=True, help_text="Person who authorises the reports."
    )
    authorised_by_role = models.CharField(
        max_length=120, blank=True, help_text="e.g. Quality manager"
    )
    created_at = models.DateTimeField(auto_now_add=True)
    updated_at = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["-created_at", "code"]
        constraints = [
            models.CheckConstraint(condition=finite_positive("en_limit"), name="cmp_en_limit_pos"),
            models.CheckConstraint(
                condition=Q(sigma_pt_value__isnull=True) | finite_positive("sigma_pt_value"),
                name="cmp_sigma_pt_pos",
            ),
            models.CheckConstraint(
                condition=Q(status__in=ComparisonStatus.values), name="cmp_status_valid"
            ),
        ]

    def __str__(self) -> str:
        return self.code


class Device(models.Model):
    """A circulated artefact (device under test) with its nominal sensitivity."""

    comparison = models.ForeignKey(Comparison, on_delete=models.CASCADE, related_name="devices")
    name = models.CharField(max_length=80, help_text="e.g. MEMS 1")
    model = models.CharField(max_length=80, blank=True, help_text="e.g. LSM6DSR")
    serial = models.CharField(max_length=80, blank=True)
    unit = models.CharField(max_length=20, default=DEFAULT_UNIT)
    nominal_sensitivity = models.FloatField(null=True, blank=True)
    tolerance = models.FloatField(null=True, blank=True, help_text="Half-width of the tolerance.")
    tolerance_relative = models.BooleanField(default=True, help_text="Tolerance given in %.")
    tolerance_distribution = models.CharField(
        max_length=12, choices=Distribution.choices, default=Distribution.RECTANGULAR
    )

    class Meta:
        ordering = ["comparison", "name"]
        constraints = [
            models.UniqueConstraint(fields=["comparison", "name"], name="device_unique_name"),
            models.CheckConstraint(
                condition=Q(nominal_sensitivity__isnull=True)
                | finite_positive("nominal_sensitivity"),
                name="device_nominal_pos",
            ),
            models.CheckConstraint(
                condition=Q(tolerance__isnull=True) | finite_positive("tolerance"),
                name="device_tolerance_pos",
            ),
        ]

    def __str__(self) -> str:
        return f"{self.name} ({self.comparison.code})" if self.comparison_id else self.name


#: The quantity kinds as model choices, from the one registry (docs/domain.md §2).
QUANTITY_CHOICES = [(k.name, k.label.capitalize()) for k in quantities.KINDS]


#: a point is unique in its round by these (and its amplitude, where it has one)
_POINT_UNIQUE = ["comparison", "device", "axis", "frequency_hz", "bench", "direction", "quantity"]


class MeasurementPoint(models.Model):
    """One measurand: device × axis × frequency × bench × direction × quantity kind (×
    optional amplitude)."""

    comparison = models.ForeignKey(
        Comparison, on_delete=models.CASCADE, related_name="measurement_points"
    )
    device = models.ForeignKey(Device, on_delete=models.CASCADE, related_name="measurement_points")
    axis = models.CharField(max_length=1, choices=Axis.choices)
    frequency_hz = models.FloatField()
    bench = models.CharField(max_length=20, choices=Bench.choices)
    direction = models.CharField(
        max_length=12, choices=Direction.choices, default=Direction.VERTICAL
    )
    quantity = models.CharField(
        max_length=16,
        choices=QUANTITY_CHOICES,
        default=quantities.DEFAULT,
        help_text="What is measured at this point: the sensitivity's magnitude or phase, or a "
        "gyroscope's angular-rate sensitivity.",
    )
    amplitude_m_s2 = models.FloatField(null=True, blank=True)
    assigned_value_method = models.CharField(
        max_length=24,
        choices=AssignedValueMethod.choices,
        blank=True,
        help_text="Overrides the comparison's method for this point when set.",
    )
    sigma_pt_value = models.FloatField(
        null=True, blank=True, help_text="Overrides the comparison's σ_pt for this point."
    )

    class Meta:
        ordering = ["device__name", "bench", "direction", "quantity", "axis", "frequency_hz"]
        constraints = [
            models.UniqueConstraint(
                fields=_POINT_UNIQUE,
                condition=Q(amplitude_m_s2__isnull=True),
                name="point_unique_no_amplitude",
            ),
            models.UniqueConstraint(
                fields=[*_POINT_UNIQUE, "amplitude_m_s2"],
                condition=Q(amplitude_m_s2__isnull=False),
                name="point_unique_with_amplitude",
            ),
            models.CheckConstraint(
                condition=finite_positive("frequency_hz"), name="point_freq_pos"
            ),
            models.CheckConstraint(
                condition=Q(amplitude_m_s2__isnull=True) | finite_positive("amplitude_m_s2"),
                name="point_amplitude_pos",
            ),
            models.CheckConstraint(condition=Q(axis__in=Axis.values), name="point_axis_valid"),
            models.CheckConstraint(
                condition=Q(quantity__in=quantities.NAMES), name="point_quantity_valid"
            ),
        ]

    def __str__(self) -> str:
        return point_label(self.key)

    @property
    def value_unit(self) -> str:
        """The unit of the point's values: the device's for a magnitude, ``deg`` for a phase
        (``common.quantities.point_unit``; reads ``device``)."""
        return quantities.point_unit(self.quantity, self.device.unit)

    @property
    def unit_shown(self) -> str:
        """:attr:`value_unit` as a person reads it (``°``, ``D/(°/s)``:
        ``common.quantities.unit_text``)."""
        return quantities.unit_text(self.value_unit)

    @property
    def quantity_label(self) -> str:
        """``sensitivity phase``: the kind as words (the registry's label)."""
        return quantities.kind(self.quantity).label

    @property
    def kind_shown(self) -> str:
        """The kind's label where a point's label names it, ``""`` for the magnitude
        (``common.quantities.label_shown``)."""
        return quantities.label_shown(self.quantity)

    @property
    def key(self) -> PointKey:
        """The point by value (reads ``device``: select it with the point)."""
        return PointKey(
            self.device.name,
            self.axis,
            self.frequency_hz,
            self.bench,
            self.direction,
            self.amplitude_m_s2,
            self.quantity,
        )


class ReferenceValue(models.Model):
    """A reference value for a measurement point: pilot result, nominal, or a computed one."""

    class Source(models.TextChoices):
        REFERENCE_LAB = "reference_lab", "Reference laboratory"
        NOMINAL = "nominal", "Nominal value"
        COMPUTED = "computed", "Computed by an analysis run"
        STABILITY_BEFORE = "stability_before", "Pilot, before circulation"
        STABILITY_AFTER = "stability_after", "Pilot, after circulation"

    measurement_point = models.ForeignKey(
        MeasurementPoint, on_delete=models.CASCADE, related_name="reference_values"
    )
    source = models.CharField(max_length=20, choices=Source.choices)
    value = models.FloatField()
    standard_uncertainty = models.FloatField()
    note = models.TextField(blank=True)
    created_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["measurement_point", "source"]
        constraints = [
            models.CheckConstraint(condition=finite_positive("value"), name="ref_value_pos"),
            models.CheckConstraint(
                condition=finite_positive("standard_uncertainty"), name="ref_u_pos"
            ),
        ]

    def __str__(self) -> str:
        return f"{self.measurement_point}: {self.value:g} ({self.get_source_display()})"


class Kit(models.Model):
    """One travelling set of the round's devices (docs/domain.md §15): a round with many
    participants circulates several identical kits, each in its own loop."""

    comparison = models.ForeignKey(Comparison, on_delete=models.CASCADE, related_name="kits")
    name = models.CharField(max_length=40, help_text="e.g. Kit A")
    note = models.CharField(max_length=500, blank=True)

    class Meta:
        ordering = ["comparison", "name"]
        constraints = [
            models.UniqueConstraint(fields=["comparison", "name"], name="kit_unique_name"),
        ]

    def __str__(self) -> str:
        return f"{self.name} ({self.comparison.code})"


class KitItem(models.Model):
    """The copy of one of the round's devices in a kit, by its serial number."""

    kit = models.ForeignKey(Kit, on_delete=models.CASCADE, related_name="items")
    device = models.ForeignKey(Device, on_delete=models.CASCADE, related_name="kit_items")
    serial = models.CharField(max_length=80)

    class Meta:
        ordering = ["kit", "device__name"]
        constraints = [
            models.UniqueConstraint(fields=["kit", "device"], name="kit_item_once"),
        ]

    def __str__(self) -> str:
        return f"{self.device.name} #{self.serial} in {self.kit.name}"
