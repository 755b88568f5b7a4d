"""Serializers of the comparison domain shared by the API modules."""

from __future__ import annotations

from typing import Any

from drf_spectacular.utils import extend_schema_field
from rest_framework import serializers

from proficiency import protocols
from proficiency.models import (
    CODE_INVALID,
    FLOAT_MAX,
    MAX_REMINDER_DAYS,
    Comparison,
    reminder_days_parse,
)

#: at most this many reminders per deadline through the API
MAX_REMINDERS = 10


def finite_positive(value: float | None) -> None:
    """The fields under a ``finite_positive`` CHECK constraint: refuse 0, negatives, NaN
    and infinity here with a 400 (the database would refuse them with an error)."""
    if value is not None and not 0 < value <= FLOAT_MAX:
        raise serializers.ValidationError(f"must be a finite number > 0, got {value}")


POSITIVE = {"validators": [finite_positive]}


@extend_schema_field(
    {
        "type": "array",
        "items": {"type": "integer", "minimum": 1, "maximum": MAX_REMINDER_DAYS},
        "maxItems": MAX_REMINDERS,
        "uniqueItems": True,
    }
)
class ReminderDaysField(serializers.ListField):
    """``reminder_days`` (docs/lifecycles.md §6) as a list of whole days before the deadline,
    ascending (``[1, 7]``); stored as the comparison's text (``7,1``). Written: distinct
    whole numbers from 1 to 365, at most :data:`MAX_REMINDERS`; ``[]`` sends none."""

    child = serializers.IntegerField(min_value=1, max_value=MAX_REMINDER_DAYS)

    def __init__(self, **kwargs: object) -> None:
        kwargs.setdefault("allow_empty", True)
        kwargs.setdefault(
            "help_text",
            "Days before the deadline on which laboratories that have not submitted are "
            f"reminded: distinct whole numbers from 1 to {MAX_REMINDER_DAYS}, at most "
            f"{MAX_REMINDERS}; [] for none.",
        )
        super().__init__(**kwargs)  # type: ignore[arg-type]

    def to_representation(self, data: object) -> list[int]:
        return reminder_days_parse(str(data or ""))

    def to_internal_value(self, data: Any) -> str:  # type: ignore[override]
        days = super().to_internal_value(data)
        # checked here: the field's validators would see the stored text, not the list
        if len(days) > MAX_REMINDERS:
            raise serializers.ValidationError(
                f"At most {MAX_REMINDERS} reminders; {len(days)} days were given."
            )
        repeated = sorted({d for d in days if days.count(d) > 1})
        if repeated:
            raise serializers.ValidationError(
                f"Each day once: {', '.join(map(str, repeated))} is given more than once."
            )
        return ",".join(str(d) for d in sorted(days, reverse=True))


class NewComparisonSerializer(serializers.ModelSerializer):
    template = serializers.ChoiceField(
        choices=list(protocols.TEMPLATES), required=False, allow_blank=True
    )
    reminder_days = ReminderDaysField(required=False)

    class Meta:
        model = Comparison
        fields = [
            "code", "title", "description", "template", "submission_deadline",
            "assigned_value_method", "sigma_pt_mode", "sigma_pt_value", "en_limit",
            "enrolment_open", "enrolment_closes",
            "reminder_days",
        ]  # fmt: skip
        extra_kwargs = {
            "sigma_pt_value": POSITIVE,
            "en_limit": POSITIVE,
            "code": {"error_messages": {"invalid": CODE_INVALID}},
        }
