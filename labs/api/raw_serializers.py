"""Request and response shapes of ``/api/v1/comparisons/{code}/raw-data/``.

The measurement point is named by the results-table columns (docs/interfaces.md §1); the
metadata keys of docs/interfaces.md §2 may come as form fields (they replace the sidecar's).
"""

from __future__ import annotations

from typing import Any

from drf_spectacular.utils import extend_schema_field
from rest_framework import serializers

from labs.api.serializers import _inline_enum
from labs.models import RawFile, RawRecomputation, RawRecord
from proficiency.models import Axis, Bench, Direction

_META_HELP = "a metadata key of the raw record's sidecar; replaces the sidecar's"


def _meta_field(help_text: str = _META_HELP) -> serializers.CharField:
    return serializers.CharField(required=False, allow_blank=True, help_text=help_text)


class RawUploadRequestSerializer(serializers.Serializer):
    file = serializers.FileField(help_text="MEMS record: CSV, or int16 little-endian")
    sidecar = serializers.FileField(required=False, help_text="JSON metadata of `file`")
    reference_file = serializers.FileField(
        required=False, help_text="Record with the `ref` or `encoder_rad` channel"
    )
    reference_sidecar = serializers.FileField(required=False)
    device = serializers.CharField(max_length=80)
    axis = serializers.ChoiceField(choices=Axis.choices)
    frequency_hz = serializers.FloatField(help_text="Excitation frequency f of the point")
    bench = serializers.ChoiceField(
        choices=[c for c in Bench.choices if c[0] in ("linear", "curvilinear")]
    )
    direction = serializers.ChoiceField(choices=Direction.choices, required=False)
    amplitude_m_s2 = serializers.FloatField(required=False, allow_null=True)
    quantity = serializers.CharField(
        required=False,
        allow_blank=True,
        help_text="The point's quantity kind: magnitude (default, also for an empty value), "
        "phase or angular_rate; it decides which recomputed figure is compared",
    )
    channels = _meta_field("Channel names in file order, comma-separated or a JSON list")
    fs_nominal_hz = _meta_field()
    fs_hz = _meta_field()
    unit = _meta_field("digits or m/s^2")
    full_scale_g = _meta_field()
    a_ref_m_s2 = _meta_field()
    tilt_deg = _meta_field()
    rotation_deg = _meta_field()
    radius_m = _meta_field()
    reference_radius_m = _meta_field()
    orientation = _meta_field('JSON, e.g. {"x": "tangential", "y": "radial", "z": "axial"}')
    oscillation_angle_deg = _meta_field()
    zones = _meta_field('JSON, e.g. {"before": [0, 10]}')
    trigger_offset_s = _meta_field("Phase: first sample minus the reference record's (s)")
    u_trigger_offset_s = _meta_field("Phase: standard uncertainty of trigger_offset_s (s)")
    start_time_s = _meta_field("Phase: first sample on a clock shared with the reference (s)")
    gyro_unit = _meta_field("Gyroscope channels gx, gy, gz: digits or deg/s")
    gyro_full_scale_dps = _meta_field()
    u_encoder_scale_rel = _meta_field("Relative u of the encoder's angle scale (gyroscope)")
    reference_channels = _meta_field("Channels of the reference record")
    reference_fs_hz = _meta_field("Exact sampling rate of the reference record")
    reference_start_time_s = _meta_field("Phase: the reference record's start_time_s")


REFERENCE_KEYS = ("reference_channels", "reference_fs_hz", "reference_start_time_s")


def reference_fields(data: dict[str, Any]) -> dict[str, Any]:
    """``reference_<key>`` form fields as the reference record's metadata fields."""
    return {k.removeprefix("reference_"): v for k, v in data.items() if k in REFERENCE_KEYS}


class RawFileSerializer(serializers.ModelSerializer):
    class Meta:
        model = RawFile
        fields = ["sha256", "size"]


@extend_schema_field(_inline_enum("RawRecomputationStatus", list(RawRecomputation.Status.values)))
class RecomputationStatusField(serializers.CharField):
    """Named inline enum: "status" is also the name of other enums (see serializers.py)."""


class RecomputationSerializer(serializers.ModelSerializer):
    status = RecomputationStatusField(read_only=True)
    reported_standard_uncertainty = serializers.FloatField(read_only=True)

    class Meta:
        model = RawRecomputation
        fields = [
            "status", "error", "method", "software_version", "parameters", "fs_hz", "u_fs_hz",
            "sensitivity", "standard_uncertainty", "expanded_uncertainty", "coverage_factor",
            "axes", "budget", "reported_value", "reported_expanded_uncertainty",
            "reported_coverage_factor", "reported_standard_uncertainty", "en", "created_at",
            "started_at", "finished_at",
        ]  # fmt: skip


class RawRecordSerializer(serializers.ModelSerializer):
    participant = serializers.CharField(source="participant.code", read_only=True)
    submission_version = serializers.IntegerField(source="submission.version", read_only=True)
    device = serializers.CharField(source="measurement_point.device.name", read_only=True)
    axis = serializers.CharField(source="measurement_point.axis", read_only=True)
    frequency_hz = serializers.FloatField(source="measurement_point.frequency_hz", read_only=True)
    bench = serializers.CharField(source="measurement_point.bench", read_only=True)
    direction = serializers.CharField(source="measurement_point.direction", read_only=True)
    quantity = serializers.CharField(source="measurement_point.quantity", read_only=True)
    data_file = RawFileSerializer(read_only=True)
    reference_file = RawFileSerializer(read_only=True, allow_null=True)
    recomputation = RecomputationSerializer(read_only=True)

    class Meta:
        model = RawRecord
        fields = [
            "id", "participant", "submission_version", "device", "axis", "frequency_hz",
            "bench", "direction", "quantity", "data_name", "data_file", "metadata",
            "reference_name", "reference_file", "reference_metadata", "created_at", "recomputation",
        ]  # fmt: skip
