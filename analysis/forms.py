"""GET forms of the results pages: score filters, the chosen measurement point, the factor."""

from __future__ import annotations

from typing import Any, cast

from django import forms

from analysis.core.scores import FLAG_LABELS
from analysis.graph_data import default_pair, point_choice_label
from common.forms import BootstrapMixin
from common.points import POINT_FIELDS, format_number
from common.quantities import DEFAULT as DEFAULT_QUANTITY
from proficiency.models import (
    QUANTITY_CHOICES,
    Axis,
    Bench,
    Comparison,
    Direction,
    MeasurementPoint,
)

ALL = [("", "All")]
FACTORS = [
    ("bench", "Bench (linear vs curvilinear)"),
    ("axis", "Axis (X, Y, Z)"),
    ("direction", "Direction"),
    ("frequency", "Frequency"),
    ("device", "Device"),
    ("lab", "Laboratory (one measurement point)"),
]


#: the flags a score carries
FLAGS = [(label, label) for label in FLAG_LABELS]


class ScoreFilterForm(BootstrapMixin, forms.Form):
    """Score filters (GET); every value is checked against the comparison's own levels."""

    device = forms.ChoiceField(required=False)
    axis = forms.ChoiceField(required=False, choices=ALL + list(Axis.choices))
    frequency_hz = forms.ChoiceField(required=False, label="Frequency (Hz)")
    bench = forms.ChoiceField(required=False, choices=ALL + list(Bench.choices))
    direction = forms.ChoiceField(required=False, choices=ALL + list(Direction.choices))
    quantity = forms.ChoiceField(required=False, choices=ALL + QUANTITY_CHOICES)
    lab = forms.ChoiceField(required=False, label="Participant")
    flag = forms.ChoiceField(required=False, label="En flag", choices=ALL + FLAGS)
    z_flag = forms.ChoiceField(required=False, label="z / z′ flag", choices=ALL + FLAGS)
    order = forms.ChoiceField(
        required=False, label="Sort by",
        choices=[("", "Point"), ("en", "|En|, largest first"), ("z", "|z| or |z′|, largest first")],
    )  # fmt: skip

    def __init__(self, data: Any, *, comparison: Comparison, lab_codes: list[str]) -> None:
        super().__init__(data)
        points = comparison.measurement_points
        devices = comparison.devices.order_by("name").values_list("name", flat=True)
        # the levels the round has, in one query: frequencies and the three named levels
        present = set(
            points.order_by()
            .values_list("axis", "bench", "direction", "frequency_hz", "quantity")
            .distinct()
        )
        freqs = sorted({row[3] for row in present})
        cast(forms.ChoiceField, self.fields["device"]).choices = ALL + [(d, d) for d in devices]
        cast(forms.ChoiceField, self.fields["frequency_hz"]).choices = ALL + [
            (repr(f), format_number(f)) for f in freqs
        ]
        cast(forms.ChoiceField, self.fields["lab"]).choices = ALL + [(c, c) for c in lab_codes]
        for i, (name, levels) in enumerate(
            (("axis", Axis.choices), ("bench", Bench.choices), ("direction", Direction.choices))
        ):
            values = {row[i] for row in present}
            cast(forms.ChoiceField, self.fields[name]).choices = ALL + [
                (value, label) for value, label in levels if value in values
            ]
        kinds = {row[4] for row in present}
        if kinds == {DEFAULT_QUANTITY}:  # a round of magnitudes: no kind to choose
            del self.fields["quantity"]
        else:
            cast(forms.ChoiceField, self.fields["quantity"]).choices = ALL + [
                (value, label) for value, label in QUANTITY_CHOICES if value in kinds
            ]

    def filters(self) -> dict[str, str]:
        """The valid filters as ``run_scores`` takes them (an invalid form filters nothing)."""
        if not self.is_valid():
            return {}
        return {k: v for k, v in self.cleaned_data.items() if v and k != "order"}

    def ordering(self) -> str:
        """The order chosen (``en``, ``z``), or "" for the points' order."""
        return str(self.cleaned_data.get("order") or "") if self.is_valid() else ""


class PointForm(BootstrapMixin, forms.Form):
    point = forms.TypedChoiceField(coerce=int, required=False, label="Measurement point")

    def __init__(self, data: Any, *, points: list[MeasurementPoint]) -> None:
        super().__init__(data)
        cast(forms.ChoiceField, self.fields["point"]).choices = [
            (p.pk, point_choice_label(p)) for p in points
        ]
        self.points = {p.pk: p for p in points}

    def chosen(self) -> MeasurementPoint | None:
        """The chosen point, else the first one (None when there is no point)."""
        pk = self.cleaned_data.get("point") if self.is_valid() else None
        return self.points.get(pk) if pk else next(iter(self.points.values()), None)


class CompatibilityForm(ScoreFilterForm):
    factor = forms.ChoiceField(choices=FACTORS, required=False)
    point = forms.TypedChoiceField(
        coerce=int, required=False, label="Point (for the laboratory matrix)"
    )

    def __init__(self, data: Any, *, comparison: Comparison, points: list[MeasurementPoint]):
        super().__init__(data, comparison=comparison, lab_codes=[])
        del self.fields["lab"]
        cast(forms.ChoiceField, self.fields["point"]).choices = [
            (p.pk, point_choice_label(p)) for p in points
        ]
        self.points = {p.pk: p for p in points}

    def chosen_factor(self) -> str:
        return (self.cleaned_data.get("factor") if self.is_valid() else "") or "bench"

    def point_filters(self) -> dict[str, str]:
        """The keys of the chosen point (default: the first) for ``lab_matrices``."""
        pk = self.cleaned_data.get("point") if self.is_valid() else None
        p = self.points.get(pk) if pk else next(iter(self.points.values()), None)
        if p is None:
            return {}
        # as text, the frequency in full (repr): lab_matrices reads them as GET filters
        return {k: str(v) for k, v in zip(POINT_FIELDS, p.key.measurand, strict=True)}


class PairForm(BootstrapMixin, forms.Form):
    """The Youden plot's pair of points (``"<pk>-<pk>"``, from ``graph_data.point_pairs``)."""

    pair = forms.ChoiceField(required=False, label="Pair of points (Youden plot)")

    def __init__(self, data: Any, *, pairs: list[tuple[str, str]]) -> None:
        super().__init__(data)
        cast(forms.ChoiceField, self.fields["pair"]).choices = pairs
        self.pairs = dict(pairs)

    def chosen(self, point: int | None = None) -> tuple[int, int] | None:
        """The chosen pair's two point ids, else the first pair of ``point`` (the chosen
        point), else the first pair (None: no pair)."""
        key = self.cleaned_data.get("pair") if self.is_valid() else None
        key = key or default_pair(list(self.pairs.items()), point)
        if key is None:
            return None
        a, b = key.split("-")
        return int(a), int(b)
