"""Request and response shapes of the API (documented in the OpenAPI schema).

Results use the column names of the results table (docs/interfaces.md §1), so a row
read from the API can be written back into a table and vice versa.
"""

from __future__ import annotations

from typing import Any

from drf_spectacular.utils import extend_schema_field
from rest_framework import serializers

from common import quantities
from common.api import valid_data
from common.rendering import ValuesRendering
from labs.models import Result, Submission
from labs.services import Scope
from proficiency.models import Comparison, ComparisonStatus, Device, MeasurementPoint
from proficiency.serializers import ReminderDaysField
from proficiency.services import DEVICE_FIELDS

# ---------------------------------------------------------------- errors


class RowErrorSerializer(serializers.Serializer):
    row = serializers.IntegerField(allow_null=True, help_text="Row (file) or 1-based index (JSON)")
    field = serializers.CharField(allow_null=True, help_text="Column, or null for the whole row")
    message = serializers.CharField()


class ErrorSerializer(serializers.Serializer):
    """Every error answer: ``{"detail": "...", "errors": [{"row", "field", "message"}]}``."""

    detail = serializers.CharField()
    # a field: the serializer metaclass moves it into _declared_fields, .errors stays
    errors = RowErrorSerializer(many=True)  # type: ignore[assignment]


def as_row_errors(errors: dict[str, Any]) -> list[dict[str, object]]:
    """DRF serializer errors -> the ``errors`` list of docs/interfaces.md §3."""
    out: list[dict[str, object]] = []
    for field, messages in errors.items():
        for message in messages if isinstance(messages, list) else [messages]:
            name = None if field == "non_field_errors" else field
            out.append({"row": None, "field": name, "message": str(message)})
    return out


# ---------------------------------------------------------------- status fields

# Comparison.status and Submission.status share the field name "status", which
# drf-spectacular's enum post-processing would turn into two colliding "StatusEnum"
# components (a warning, fatal with --fail-on-warn). Wrapped in allOf, each stays an
# inline, named enum. (ENUM_NAME_OVERRIDES in SPECTACULAR_SETTINGS would do it too.)


def _inline_enum(title: str, values: list[str]) -> dict[str, object]:
    return {"allOf": [{"title": title, "type": "string", "enum": values}], "readOnly": True}


@extend_schema_field(_inline_enum("ComparisonStatus", list(ComparisonStatus.values)))
class ComparisonStatusField(serializers.CharField):
    pass


@extend_schema_field(_inline_enum("SubmissionStatus", list(Submission.Status.values)))
class SubmissionStatusField(serializers.CharField):
    pass


# ---------------------------------------------------------------- scopes


class ScopeSerializer(serializers.Serializer):
    """A participant's scope (docs/domain.md §10); an empty or absent list allows every value."""

    devices = serializers.ListField(child=serializers.CharField(), required=False, default=list)
    benches = serializers.ListField(child=serializers.CharField(), required=False, default=list)
    axes = serializers.ListField(child=serializers.CharField(), required=False, default=list)
    frequencies_hz = serializers.ListField(
        child=serializers.FloatField(), required=False, default=list
    )

    def scope(self) -> Scope:
        data = valid_data(self)
        return Scope(
            devices=data["devices"],
            benches=data["benches"],
            axes=data["axes"],
            frequencies_hz=data["frequencies_hz"],
        )


# ---------------------------------------------------------------- comparisons


class ComparisonSerializer(serializers.ModelSerializer):
    status = ComparisonStatusField(read_only=True)

    class Meta:
        model = Comparison
        fields = ["code", "title", "protocol", "status", "submission_deadline"]


class DeviceSerializer(serializers.ModelSerializer):
    class Meta:
        model = Device
        fields = DEVICE_FIELDS


class ComparisonDetailSerializer(serializers.ModelSerializer):
    """``participant_code`` is the caller's own code (null for a coordinator only)."""

    status = ComparisonStatusField(read_only=True)
    devices = DeviceSerializer(many=True, read_only=True)
    n_measurement_points = serializers.SerializerMethodField()
    participant_code = serializers.SerializerMethodField()
    roles = serializers.SerializerMethodField()
    reminder_days = ReminderDaysField(read_only=True)

    class Meta:
        model = Comparison
        fields = [
            "code",
            "title",
            "description",
            "protocol",
            "status",
            "submission_deadline",
            "en_limit",
            "reminder_days",
            "devices",
            "n_measurement_points",
            "participant_code",
            "roles",
            "enrolment_open",
            "enrolment_closes",
        ]

    def get_n_measurement_points(self, obj: Comparison) -> int:
        return obj.measurement_points.count()

    def get_participant_code(self, obj: Comparison) -> str | None:
        participant = self.context["access"].participant
        return participant.code if participant is not None else None

    def get_roles(self, obj: Comparison) -> list[str]:
        access = self.context["access"]
        roles = ["participant"] if access.participant is not None else []
        return [*roles, "coordinator"] if access.is_coordinator else roles


DEVICE_ROWS = ValuesRendering(DeviceSerializer)
COMPARISON_DETAIL = ValuesRendering(
    ComparisonDetailSerializer,
    computed=("devices", "n_measurement_points", "participant_code", "roles"),
)


def comparison_detail_data(comparison: Comparison, access: Any) -> dict[str, Any]:
    """``ComparisonDetailSerializer(comparison, context={"access": access}).data``, the
    columns read without building the serializer's fields (the hot polled endpoint)."""
    methods = ComparisonDetailSerializer(context={"access": access})
    return COMPARISON_DETAIL.instance(
        comparison,
        devices=DEVICE_ROWS.data(comparison.devices.all()),
        n_measurement_points=methods.get_n_measurement_points(comparison),
        participant_code=methods.get_participant_code(comparison),
        roles=methods.get_roles(comparison),
    )


class MeasurementPointSerializer(serializers.ModelSerializer):
    device = serializers.CharField(source="device.name")
    unit = serializers.SerializerMethodField(
        help_text="Unit of the value: the device's for a magnitude, deg for a phase, "
        "D/(deg/s) for an angular rate"
    )
    in_scope = serializers.SerializerMethodField(
        help_text="For a participant: whether the point is in its scope, i.e. whether it reports "
        "a result there; null for a coordinator who does not take part"
    )

    class Meta:
        model = MeasurementPoint
        fields = [
            "device",
            "axis",
            "frequency_hz",
            "bench",
            "direction",
            "quantity",
            "amplitude_m_s2",
            "unit",
            "in_scope",
        ]

    def get_unit(self, obj: MeasurementPoint) -> str:
        """The view's annotation (``labs.selectors.point_unit_expression``), or the same rule."""
        annotated = getattr(obj, "point_unit", None)
        return annotated or quantities.point_unit(obj.quantity, obj.device.unit)

    def get_in_scope(self, obj: MeasurementPoint) -> bool | None:
        return getattr(obj, "in_scope", None)  # the view's annotation (labs.selectors.scope_flag)


# ---------------------------------------------------------------- submissions


class ResultRowInSerializer(serializers.Serializer):
    """One result as sent (documentation only: rows are validated by the importer, which
    reports every problem by row and column)."""

    device = serializers.CharField(help_text="Artefact name as in the comparison, e.g. MEMS 1")
    axis = serializers.ChoiceField(choices=["X", "Y", "Z"])
    frequency_hz = serializers.FloatField()
    bench = serializers.CharField(help_text="linear or curvilinear")
    direction = serializers.CharField(required=False, help_text="vertical, tangential, radial")
    quantity = serializers.CharField(
        required=False,
        help_text="magnitude (default, also for an empty value), phase or angular_rate",
    )
    amplitude_m_s2 = serializers.FloatField(required=False, allow_null=True)
    sensitivity = serializers.FloatField(
        help_text="The value: > 0 for a magnitude or an angular rate; for a phase any finite "
        "number of degrees, stored wrapped into (-180, 180]"
    )
    unit = serializers.CharField(required=False, help_text="Default: the device's unit")
    expanded_uncertainty = serializers.CharField(
        help_text="Number > 0 in the unit of sensitivity, or a string with a % suffix"
    )
    coverage_factor = serializers.FloatField(required=False, help_text="Default 2")
    dof = serializers.FloatField(required=False, allow_null=True)
    repeat_sd = serializers.FloatField(
        required=False, allow_null=True,
        help_text="Within-laboratory standard deviation (> 0, unit of sensitivity) of the "
        "repeats whose mean is sensitivity; give n_repeats with it",
    )  # fmt: skip
    n_repeats = serializers.IntegerField(
        required=False, allow_null=True, min_value=2,
        help_text="Number of repeats behind repeat_sd (whole number >= 2); give repeat_sd with it",
    )  # fmt: skip
    measured_on = serializers.DateField(
        required=False, allow_null=True,
        help_text="The date the laboratory measured the result, YYYY-MM-DD (null or absent: "
        "not stated); not before the comparison's first day nor in the future. A kit's "
        "drift is taken at it",
    )  # fmt: skip
    note = serializers.CharField(required=False, max_length=500)


class RowsField(serializers.ListField):
    """A JSON array, passed on untouched: the importer checks each row (docs/interfaces.md §1)."""

    def to_internal_value(self, data: Any) -> list[Any]:
        if not isinstance(data, list):
            self.fail("not_a_list", input_type=type(data).__name__)
        return data


class SubmissionRequestSerializer(serializers.Serializer):
    results = RowsField(
        child=ResultRowInSerializer(),
        help_text="One object per result, keys as the columns of the results table "
        "(`lab` is not allowed). Numbers may be JSON numbers or strings.",
    )
    submit = serializers.BooleanField(
        default=True,
        help_text="true: submit (needs a result for every measurement point); "
        "false: save as the open draft.",
    )


class UploadRequestSerializer(serializers.Serializer):
    file = serializers.FileField(
        help_text="Results table (CSV or XLSX) with the results template's columns"
    )
    submit = serializers.BooleanField(default=True)


class SubmissionSerializer(serializers.ModelSerializer):
    participant = serializers.CharField(source="participant.code", help_text="Participant code")
    status = SubmissionStatusField(read_only=True)
    n_results = serializers.SerializerMethodField()

    class Meta:
        model = Submission
        fields = [
            "participant",
            "version",
            "status",
            "source",
            "created_at",
            "submitted_at",
            "decided_at",
            "message",
            "n_results",
        ]

    def get_n_results(self, obj: Submission) -> int:
        annotated = getattr(obj, "n_results", None)
        return annotated if annotated is not None else obj.results.count()


class ResultSerializer(serializers.ModelSerializer):
    device = serializers.CharField(source="measurement_point.device.name")
    axis = serializers.CharField(source="measurement_point.axis")
    frequency_hz = serializers.FloatField(source="measurement_point.frequency_hz")
    bench = serializers.CharField(source="measurement_point.bench")
    direction = serializers.CharField(source="measurement_point.direction")
    quantity = serializers.CharField(source="measurement_point.quantity")
    amplitude_m_s2 = serializers.FloatField(
        source="measurement_point.amplitude_m_s2", allow_null=True
    )
    sensitivity = serializers.FloatField(source="value")

    class Meta:
        model = Result
        fields = [
            "device",
            "axis",
            "frequency_hz",
            "bench",
            "direction",
            "quantity",
            "amplitude_m_s2",
            "sensitivity",
            "unit",
            "expanded_uncertainty",
            "coverage_factor",
            "standard_uncertainty",
            "dof",
            "repeat_sd",
            "n_repeats",
            "measured_on",
            "note",
        ]


class SubmissionDetailSerializer(SubmissionSerializer):
    results = serializers.SerializerMethodField()

    class Meta(SubmissionSerializer.Meta):
        fields = [*SubmissionSerializer.Meta.fields, "results"]

    @extend_schema_field(ResultSerializer(many=True))
    def get_results(self, obj: Submission) -> list[dict[str, Any]]:
        # ResultSerializer's output, from values_list rows (81+ rows per version)
        return RESULT_ROWS.data(self.context["results"])


RESULT_ROWS = ValuesRendering(ResultSerializer)
SUBMISSION_DETAIL = ValuesRendering(SubmissionDetailSerializer, computed=("n_results", "results"))


def submission_detail_data(submission: Submission, results: Any) -> dict[str, Any]:
    """``SubmissionDetailSerializer(submission, context={"results": results}).data``, the
    columns read without building the serializer's fields."""
    rows = SubmissionDetailSerializer(context={"results": results}).get_results(submission)
    # the version's results are all listed: their number is its n_results
    return SUBMISSION_DETAIL.instance(submission, n_results=len(rows), results=rows)
