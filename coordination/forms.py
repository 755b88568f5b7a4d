"""Forms of the coordinator pages: comparison settings, devices, the point grid, overrides,
invitations and review decisions.  They collect and check input; the writes are services."""

from __future__ import annotations

from typing import Any, cast

from django import forms

from common.forms import BootstrapMixin, ByName
from common.points import format_number
from labs.models import Laboratory, Participant
from labs.selectors import REVIEW_STATUSES
from labs.services import Scope
from proficiency import protocols
from proficiency.models import (
    CODE_INVALID,
    AssignedValueMethod,
    Axis,
    Bench,
    Comparison,
    Device,
    Direction,
    DriftTreatment,
    MeasurementPoint,
)
from proficiency.selectors import call_levels
from proficiency.services import DEVICE_FIELDS

TEMPLATE_CHOICES = [("", "From scratch (add devices and points yourself)")] + [
    (key, t.title) for key, t in protocols.TEMPLATES.items()
]


class ComparisonForm(BootstrapMixin, forms.ModelForm):
    class Meta:
        model = Comparison
        fields = [
            "code",
            "title",
            "description",
            "submission_deadline",
            "assigned_value_method",
            "sigma_pt_mode",
            "sigma_pt_value",
            "en_limit",
            "drift_treatment",
            "reminder_days",
            "enrolment_open",
            "enrolment_closes",
        ]
        widgets = {
            "description": forms.Textarea(attrs={"rows": 3}),
            "submission_deadline": forms.DateTimeInput(
                attrs={"type": "datetime-local"}, format="%Y-%m-%dT%H:%M"
            ),
            "enrolment_closes": forms.DateTimeInput(
                attrs={"type": "datetime-local"}, format="%Y-%m-%dT%H:%M"
            ),
        }
        error_messages = {"code": {"invalid": CODE_INVALID}}
        labels = {
            "sigma_pt_mode": "σ_pt mode",
            "sigma_pt_value": "σ_pt value",
            "en_limit": "En limit",
            "drift_treatment": "A drifting kit",
            "enrolment_open": "Open for applications",
            "enrolment_closes": "Enrolment closes",
        }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # a form posted without it (an older page, a script) keeps the round's setting
        self.fields["drift_treatment"].required = False

    def clean_drift_treatment(self) -> str:
        chosen = self.cleaned_data.get("drift_treatment")
        return chosen or self.instance.drift_treatment or DriftTreatment.CORRECT

    def clean(self) -> dict[str, Any]:
        data = cast(dict[str, Any], super().clean())  # ModelForm.clean: its cleaned_data
        mode, value = data.get("sigma_pt_mode"), data.get("sigma_pt_value")
        if mode in ("absolute", "relative") and not value:
            self.add_error("sigma_pt_value", "A prescribed σ_pt needs a value > 0.")
        return data


class ComparisonCreateForm(ComparisonForm):
    template = forms.ChoiceField(
        choices=TEMPLATE_CHOICES,
        required=False,
        label="Protocol template",
        help_text="A template sets the protocol; its measurement points are generated once "
        "you add devices.",
    )


class DeviceForm(BootstrapMixin, forms.ModelForm):
    class Meta:
        model = Device
        fields = DEVICE_FIELDS
        labels = {"tolerance": "Tolerance (± half-width)", "tolerance_relative": "Tolerance in %"}

    def __init__(self, *args: Any, comparison: Comparison, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.instance.comparison = comparison
        # the name's rule is proficiency.services.device_create's (docs/architecture.md §2):
        # the field only carries the text, its page keeps the required/maxlength attributes
        name = self.fields["name"]
        name.widget.attrs.update({"required": True})
        name.required, name.validators = False, []

    def _post_clean(self) -> None:
        """No model validation: the service checks the device (ModelForm would do it again)."""

    def values(self) -> dict[str, Any]:
        """The cleaned fields as ``device_create``'s keyword arguments."""
        return {f: self.cleaned_data[f] for f in self.Meta.fields}


def _floats(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
    except ValueError:
        raise forms.ValidationError("Give numbers separated by commas, e.g. 5, 10, 20.") from None
    if not values or any(not (0 < v < float("inf")) for v in values):
        raise forms.ValidationError("Give at least one frequency; each must be > 0.")
    return values


class PointGridForm(BootstrapMixin, forms.Form):
    """Generate the grid from a protocol template, or from lists of axes/frequencies/benches."""

    template = forms.ChoiceField(
        choices=[("", "Use the lists below"), *TEMPLATE_CHOICES[1:]], required=False
    )
    axes = forms.MultipleChoiceField(
        choices=Axis.choices, required=False, widget=forms.CheckboxSelectMultiple
    )
    frequencies = forms.CharField(required=False, help_text="Hz, separated by commas")
    benches = forms.MultipleChoiceField(
        choices=Bench.choices, required=False, widget=forms.CheckboxSelectMultiple
    )
    directions = forms.MultipleChoiceField(
        choices=Direction.choices,
        required=False,
        widget=forms.CheckboxSelectMultiple,
        help_text="Leave empty for each bench's own directions.",
    )

    def clean(self) -> dict[str, Any]:
        data = cast(dict[str, Any], super().clean())  # Form.clean: its cleaned_data
        if data.get("template"):
            return data
        if not data.get("axes"):
            self.add_error("axes", "Choose at least one axis (or a template).")
        if not data.get("benches"):
            self.add_error("benches", "Choose at least one bench (or a template).")
        try:
            data["frequencies_hz"] = _floats(data.get("frequencies", ""))
        except forms.ValidationError as exc:
            self.add_error("frequencies", exc)
        return data


class PointOverrideForm(BootstrapMixin, forms.ModelForm):
    class Meta:
        model = MeasurementPoint
        fields = ["assigned_value_method", "sigma_pt_value"]
        labels = {"assigned_value_method": "Assigned-value method", "sigma_pt_value": "σ_pt"}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        choices = [("", "Comparison's method"), *AssignedValueMethod.choices]
        cast(forms.ChoiceField, self.fields["assigned_value_method"]).choices = choices


def _optional_floats(text: str) -> list[float]:
    """Frequencies separated by commas, or none at all (every frequency)."""
    return _floats(text) if text.strip() else []


class ScopeForm(BootstrapMixin, forms.Form):
    """What a participant measures (docs/domain.md §10); nothing chosen in a field allows
    every value of it. ``labs.services`` checks the scope against the comparison."""

    devices = ByName(
        queryset=Device.objects.none(), required=False, widget=forms.CheckboxSelectMultiple,
        help_text="None chosen: every device.",
    )  # fmt: skip
    benches = forms.MultipleChoiceField(
        choices=Bench.choices, required=False, widget=forms.CheckboxSelectMultiple,
        help_text="None chosen: every bench.",
    )  # fmt: skip
    axes = forms.MultipleChoiceField(
        choices=Axis.choices, required=False, widget=forms.CheckboxSelectMultiple,
        help_text="None chosen: every axis.",
    )  # fmt: skip
    frequencies_hz = forms.CharField(
        required=False, label="Frequencies",
        help_text="Hz, separated by commas; empty: every frequency.",
    )  # fmt: skip

    def __init__(
        self, *args: Any, comparison: Comparison, participant: Participant | None = None,
        **kwargs: Any,
    ) -> None:  # fmt: skip
        if participant is not None and "initial" not in kwargs:
            kwargs["initial"] = {
                "devices": list(participant.scope_devices.all()),
                "benches": participant.scope_benches,
                "axes": participant.scope_axes,
                "frequencies_hz": ", ".join(map(format_number, participant.scope_frequencies_hz)),
            }
        super().__init__(*args, **kwargs)
        field = cast(forms.ModelMultipleChoiceField, self.fields["devices"])
        field.queryset = comparison.devices.order_by("name")
        # only the benches and axes the round's points have (all while it has none yet),
        # and any the participant's scope still names
        levels = call_levels([comparison])[comparison.pk]
        for name, have, choices in (
            ("benches", levels.benches, Bench.choices),
            ("axes", levels.axes, Axis.choices),
        ):
            kept = set(have) | set(self.initial.get(name) or ())
            if have:
                cast(forms.ChoiceField, self.fields[name]).choices = [
                    (value, label) for value, label in choices if value in kept
                ]

    def clean_frequencies_hz(self) -> list[float]:
        return _optional_floats(self.cleaned_data.get("frequencies_hz", ""))

    def scope(self) -> Scope:
        return Scope.of(self.cleaned_data)


class InviteForm(ScopeForm):
    """The laboratories to invite as checkboxes (no Ctrl-click); ``search`` narrows the
    laboratories offered to those whose name contains it, and ``select_all`` ticks every
    one offered: both come from the page's query string, so they work without JavaScript."""

    laboratories = forms.ModelMultipleChoiceField(
        queryset=Laboratory.objects.none(), widget=forms.CheckboxSelectMultiple
    )
    field_order = ["laboratories"]

    def __init__(
        self, *args: Any, comparison: Comparison, search: str = "", select_all: bool = False,
        **kwargs: Any,
    ) -> None:  # fmt: skip
        super().__init__(*args, comparison=comparison, **kwargs)
        field = cast(forms.ModelMultipleChoiceField, self.fields["laboratories"])
        uninvited = Laboratory.objects.exclude(participations__comparison=comparison)
        self.n_uninvited = uninvited.count()
        offered = uninvited.filter(name__icontains=search) if search else uninvited
        field.queryset = offered.order_by("name")
        if select_all and not self.is_bound:
            self.initial["laboratories"] = list(field.queryset)


class DecisionForm(BootstrapMixin, forms.Form):
    decision = forms.ChoiceField(choices=[("accept", "Accept"), ("reject", "Reject")])
    message = forms.CharField(
        required=False,
        widget=forms.Textarea(attrs={"rows": 3}),
        help_text="Required for a rejection: the laboratory reads it.",
    )


class DeclineForm(BootstrapMixin, forms.Form):
    reason = forms.CharField(
        required=False, max_length=2_000, widget=forms.Textarea(attrs={"rows": 3}),
        help_text="Required: the laboratory reads it (e.g. the round is full for that bench).",
    )  # fmt: skip


_SMALL = "form-select form-select-sm"


class ReviewFilterForm(forms.Form):
    """The review list's filters (GET): a latest version's status, its completeness. A
    value that is not offered is ignored, as if not given."""

    status = forms.ChoiceField(required=False, widget=forms.Select(attrs={"class": _SMALL}))
    complete = forms.ChoiceField(
        required=False, label="Completeness", widget=forms.Select(attrs={"class": _SMALL}),
        choices=[("", "Any"), ("complete", "Complete"), ("incomplete", "Incomplete")],
    )  # fmt: skip

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        statuses = [(s, s.capitalize()) for s in REVIEW_STATUSES if s != "none"]
        cast(forms.ChoiceField, self.fields["status"]).choices = [
            ("", "Any"),
            *statuses,
            ("none", "No submission"),
        ]

    def filters(self) -> dict[str, str]:
        """The valid filters given, by name (a bad value is dropped, the others kept)."""
        self.is_valid()
        data = getattr(self, "cleaned_data", {})
        return {
            name: data[name] for name in self.fields if name not in self.errors and data.get(name)
        }


class ReportNotesForm(BootstrapMixin, forms.Form):
    """The coordinator's comments and conclusions and the reports' authoriser (docs/domain.md §9).
    Plain text: it is escaped when printed."""

    comments = forms.CharField(
        required=False,
        max_length=20_000,
        strip=False,
        widget=forms.Textarea(attrs={"rows": 6}),
        label="Comments on performance and advice on interpretation",
    )
    conclusions = forms.CharField(
        required=False, max_length=20_000, strip=False, widget=forms.Textarea(attrs={"rows": 4})
    )
    authorised_by_name = forms.CharField(
        required=False, max_length=120, label="Authorised by (name)"
    )
    authorised_by_role = forms.CharField(
        required=False,
        max_length=120,
        label="Role",
        help_text="Final reports need both; publication is refused without them.",
    )
