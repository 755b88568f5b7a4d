"""Forms of the laboratory web pages.

The forms only collect raw text: the results are validated by the importer
behind ``labs.services.submission_from_records`` / ``submission_from_file`` (the
one path shared with the REST API), and its row errors are mapped back here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

from django import forms
from django.conf import settings
from django.core.files.uploadedfile import UploadedFile
from django.db.models import QuerySet

from common.forms import ByName
from common.points import format_number
from labs.importers.values import human_size
from labs.models import LabAPIKey, Laboratory, Result
from labs.services import Scope
from proficiency.models import Bench, Comparison, Device, MeasurementPoint

#: Grid columns, in the results-table names of docs/interfaces.md §1:
#: (label, short title, max length).
GRID_COLUMNS: dict[str, tuple[str, str, int]] = {
    "sensitivity": ("Sensitivity", "Sensitivity", 40),
    "expanded_uncertainty": ("Expanded uncertainty U", "U", 40),
    "coverage_factor": ("Coverage factor k", "k", 20),
    "dof": ("Degrees of freedom", "dof", 20),
    "repeat_sd": ("Standard deviation of the repeats", "s", 40),
    "n_repeats": ("Number of repeats", "n", 20),
    "measured_on": ("Date measured", "Date", 40),
    "note": ("Note", "Note", 500),
}
#: Asked only in a round with kits (their drift is taken at it, docs/domain.md §13).
DATED_COLUMNS = ("measured_on",)
#: A row with none of these filled in is left out (a partial draft is allowed).
CONTENT_COLUMNS = ("sensitivity", "expanded_uncertainty", "dof", "repeat_sd", "n_repeats",
                   "measured_on", "note")  # fmt: skip
DEFAULT_K = "2"


def _number(value: float | None) -> str:
    return "" if value is None else format_number(value)


@dataclass(frozen=True)
class GridCell:
    column: str
    title: str
    bound: forms.BoundField


@dataclass
class GridRow:
    """One measurement point of the grid with its bound inputs and row-level errors."""

    index: int
    point: MeasurementPoint
    cells: list[GridCell]
    errors: list[str] = field(default_factory=list)
    missing: bool = False

    @property
    def has_errors(self) -> bool:
        return bool(self.errors) or any(cell.bound.errors for cell in self.cells)


class ResultGridForm(forms.Form):
    """One row per measurement point: sensitivity, U (absolute or ``1.5%``), k, dof, the
    optional repeatability (repeat_sd with n_repeats), in a round with kits (``dated``) the
    optional date measured, note."""

    def __init__(
        self,
        *args: Any,
        points: Sequence[MeasurementPoint],
        results: Mapping[int, Result] | None = None,
        dated: bool = False,
        **kwargs: Any,
    ) -> None:
        super().__init__(*args, **kwargs)
        self.points = list(points)
        self.dated = dated
        self.columns = {c: v for c, v in GRID_COLUMNS.items() if dated or c not in DATED_COLUMNS}
        self.summary: list[str] = []
        self.submit_refused = False
        self._row_errors: dict[int, list[str]] = {}
        self._record_rows: list[int] = []
        for i, point in enumerate(self.points):
            for name, (label, _, max_length) in self.columns.items():
                self.fields[self.key(i, name)] = forms.CharField(
                    label=f"{label}, {point}",
                    required=False,
                    max_length=max_length,
                    initial=DEFAULT_K if name == "coverage_factor" else "",
                )
        self.initial.update(self._prefill(results or {}))

    @staticmethod
    def key(index: int, column: str) -> str:
        return f"r{index}-{column}"

    def _prefill(self, results: Mapping[int, Result]) -> dict[str, str]:
        initial: dict[str, str] = {}
        for i, point in enumerate(self.points):
            result = results.get(point.pk)
            if result is None:
                continue
            initial[self.key(i, "sensitivity")] = _number(result.value)
            # a relative U as the lab wrote it (docs/domain.md §3.1), else the absolute number
            initial[self.key(i, "expanded_uncertainty")] = (
                result.expanded_uncertainty_entered or _number(result.expanded_uncertainty)
            )
            initial[self.key(i, "coverage_factor")] = _number(result.coverage_factor)
            initial[self.key(i, "dof")] = _number(result.dof)
            initial[self.key(i, "repeat_sd")] = _number(result.repeat_sd)
            initial[self.key(i, "n_repeats")] = _number(result.n_repeats)
            initial[self.key(i, "note")] = result.note
            if self.dated and result.measured_on is not None:
                initial[self.key(i, "measured_on")] = result.measured_on.isoformat()
        return initial

    def _is_blank(self, index: int) -> bool:
        data = self.cleaned_data
        return not any((data.get(self.key(index, c)) or "").strip() for c in CONTENT_COLUMNS)

    def records(self) -> list[dict[str, object]]:
        """The filled-in rows as results-table records, in grid order (call after is_valid)."""
        records, self._record_rows = [], []
        for i, point in enumerate(self.points):
            if self._is_blank(i):
                continue
            record: dict[str, object] = {
                "device": point.device.name,
                "axis": point.axis,
                "frequency_hz": point.frequency_hz,
                "bench": point.bench,
                "direction": point.direction,
                "quantity": point.quantity,
                "amplitude_m_s2": point.amplitude_m_s2,
            }
            for column in self.columns:
                value = (self.cleaned_data.get(self.key(i, column)) or "").strip()
                record[column] = value or None
            records.append(record)
            self._record_rows.append(i)
        return records

    def add_service_errors(
        self, message: str, errors: Iterable[Mapping[str, Any]], *, submit: bool
    ) -> None:
        """Put the service's row errors next to the inputs they concern, the rest on top."""
        self.summary.append(message)
        for error in errors:
            row, column, text = error.get("row"), error.get("field"), error["message"]
            index = self._grid_index(row)
            if index is None:
                self.summary.append(text)
            elif column in self.columns:
                self.add_error(self.key(index, column), text)
            else:
                self._row_errors.setdefault(index, []).append(text)
        self.submit_refused = submit and any(e.get("row") is None for e in errors)

    def _grid_index(self, row: object) -> int | None:
        if isinstance(row, int) and 1 <= row <= len(self._record_rows):
            return self._record_rows[row - 1]
        return None

    @property
    def rows(self) -> list[GridRow]:
        out = []
        for i, point in enumerate(self.points):
            cells = [
                GridCell(column, title, self[self.key(i, column)])
                for column, (_, title, _) in self.columns.items()
            ]
            missing = self.submit_refused and self._is_blank(i)
            out.append(GridRow(i, point, cells, self._row_errors.get(i, []), missing))
        return out

    @property
    def error_count(self) -> int:
        return sum(1 for row in self.rows if row.has_errors)


class ResultUploadForm(forms.Form):
    """A CSV or XLSX results table (docs/interfaces.md §1), refused above MAX_UPLOAD_BYTES."""

    file = forms.FileField(
        label="Results file (CSV or XLSX)",
        widget=forms.ClearableFileInput(
            attrs={
                "accept": ".csv,.xlsx,text/csv,"
                "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
                "class": "form-control",
            }
        ),
    )

    def clean_file(self) -> UploadedFile:
        upload: UploadedFile = self.cleaned_data["file"]
        limit = settings.MAX_UPLOAD_BYTES
        if upload.size is not None and upload.size > limit:
            raise forms.ValidationError(
                f"The file is {human_size(upload.size)}; the limit is {human_size(limit)}. "
                "Split it or remove unused columns and upload again.",
                code="too_large",
            )
        return upload

    def content(self) -> bytes:
        upload: UploadedFile = self.cleaned_data["file"]
        return b"".join(upload.chunks())


class APIKeyCreateForm(forms.Form):
    name = forms.CharField(
        label="Key name",
        max_length=LabAPIKey._meta.get_field("name").max_length,
        help_text="What uses the key, e.g. the calibration software or the computer.",
        widget=forms.TextInput(attrs={"class": "form-control", "autocomplete": "off"}),
    )


class ApplicationForm(forms.Form):
    """A laboratory's application to an open call: the scope it measures, chosen among the
    round's own devices, benches, axes and frequencies (nothing ticked in a group: every
    value of it), and a note. ``labs.enrolment`` checks it as an invitation's scope."""

    laboratory = forms.ModelChoiceField(
        queryset=Laboratory.objects.none(), widget=forms.RadioSelect, empty_label=None,
        label="Laboratory applying",
    )  # fmt: skip
    devices = ByName(
        queryset=Device.objects.none(), required=False, widget=forms.CheckboxSelectMultiple,
        help_text="None ticked: every device.",
    )  # fmt: skip
    benches = forms.MultipleChoiceField(
        required=False, widget=forms.CheckboxSelectMultiple, help_text="None ticked: every bench."
    )
    axes = forms.MultipleChoiceField(
        required=False, widget=forms.CheckboxSelectMultiple, help_text="None ticked: every axis."
    )
    frequencies_hz = forms.TypedMultipleChoiceField(
        coerce=float, required=False, widget=forms.CheckboxSelectMultiple, label="Frequencies",
        help_text="None ticked: every frequency.",
    )  # fmt: skip
    note = forms.CharField(
        required=False, max_length=2_000, widget=forms.Textarea(attrs={"rows": 3}),
        label="Note to the coordinator", help_text="Optional, e.g. your bench's range.",
    )  # fmt: skip

    def __init__(
        self, *args: Any, comparison: Comparison, levels: Any,
        laboratories: QuerySet[Laboratory], **kwargs: Any,
    ) -> None:  # fmt: skip
        super().__init__(*args, **kwargs)
        f = self.fields
        cast(forms.ModelChoiceField, f["laboratory"]).queryset = laboratories
        if len(laboratories) == 1:
            f["laboratory"].initial = laboratories[0]
            f["laboratory"].widget = forms.HiddenInput()
        devices = cast(forms.ModelMultipleChoiceField, f["devices"])
        devices.queryset = comparison.devices.order_by("name")
        bench_names = dict(Bench.choices)
        cast(forms.ChoiceField, f["benches"]).choices = [
            (b, bench_names.get(b, b)) for b in levels.benches
        ]
        cast(forms.ChoiceField, f["axes"]).choices = [(a, a) for a in levels.axes]
        cast(forms.ChoiceField, f["frequencies_hz"]).choices = [
            (format_number(v), f"{format_number(v)} Hz") for v in levels.frequencies_hz
        ]
        for each in f.values():
            if isinstance(each.widget, forms.CheckboxSelectMultiple | forms.RadioSelect):
                each.widget.attrs.setdefault("class", "form-check-input")
            elif not isinstance(each.widget, forms.HiddenInput):
                each.widget.attrs.setdefault("class", "form-control")

    def scope(self) -> Scope:
        return Scope.of(self.cleaned_data)
