"""The web form for raw records: the same fields as the API (docs/interfaces.md §1 point columns,
docs/interfaces.md §2 metadata keys); ``labs.raw_services`` validates the content."""

from __future__ import annotations

from typing import Any, cast

from django import forms

from proficiency.models import MeasurementPoint


class RawUploadForm(forms.Form):
    point = forms.ModelChoiceField(
        queryset=MeasurementPoint.objects.none(),
        label="Measurement point",
        help_text="The result (of your current submission) the record is behind.",
    )
    file = forms.FileField(label="MEMS record", help_text="CSV, or int16 little-endian (.bin)")
    sidecar = forms.FileField(required=False, label="Sidecar (JSON metadata)")
    reference_file = forms.FileField(
        required=False, label="Reference record", help_text="ref or encoder_rad channel"
    )
    reference_sidecar = forms.FileField(required=False, label="Reference sidecar (JSON)")
    channels = forms.CharField(required=False, help_text="e.g. x,y,z (binary files)")
    fs_nominal_hz = forms.CharField(required=False, label="Nominal rate (Hz)")
    a_ref_m_s2 = forms.CharField(required=False, label="a_ref (m/s²), linear bench")
    tilt_deg = forms.CharField(required=False, label="Tilt θ (°)")
    rotation_deg = forms.CharField(required=False, label="Rotation α (°)")
    radius_m = forms.CharField(required=False, label="Radius (m), curvilinear bench")
    orientation = forms.CharField(
        required=False, help_text='JSON, e.g. {"x": "tangential", "y": "radial", "z": "axial"}'
    )
    reference_fs_hz = forms.CharField(required=False, label="Reference record rate (Hz)")
    trigger_offset_s = forms.CharField(
        required=False, label="Trigger offset (s), for the phase",
        help_text="first sample of this record minus the reference record's, on one clock",
    )  # fmt: skip
    u_trigger_offset_s = forms.CharField(required=False, label="u(trigger offset) (s)")
    start_time_s = forms.CharField(
        required=False, label="Start time (s)", help_text="first sample, on a clock shared "
        "with the reference record (give the reference's too)",
    )  # fmt: skip
    reference_start_time_s = forms.CharField(required=False, label="Reference start time (s)")
    gyro_unit = forms.CharField(required=False, help_text="gx, gy, gz: digits or deg/s")
    u_encoder_scale_rel = forms.CharField(
        required=False, label="u_rel(encoder angle scale)", help_text="gyroscope budget, e.g. 0.001"
    )

    def __init__(self, *args: Any, points: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        point = cast(forms.ModelChoiceField, self.fields["point"])
        point.queryset = points
        point.label_from_instance = str  # type: ignore[method-assign,assignment]

    def point_fields(self) -> dict[str, Any]:
        p = self.cleaned_data["point"]
        return dict(p.key._asdict())

    def meta_fields(self) -> dict[str, Any]:
        return {k: v for k, v in self.cleaned_data.items()
                if isinstance(v, str) and not k.startswith("reference_")}  # fmt: skip

    def reference_fields(self) -> dict[str, Any]:
        return {"fs_hz": self.cleaned_data.get("reference_fs_hz", ""),
                "start_time_s": self.cleaned_data.get("reference_start_time_s", "")}  # fmt: skip
