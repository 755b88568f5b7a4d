"""Serializers of the comparison domain shared by the API modules."""

from __future__ import annotations

from rest_framework import serializers

from proficiency import protocols
from proficiency.models import CODE_INVALID, FLOAT_MAX, Comparison


def finite_positive(value: float | None) -> None:
    """The fields under a ``finite_positive`` CHECK constraint: refuse 0, negatives, NaN
    and infinity here with a 400 (the database would refuse them with an error)."""
    if value is not None and not 0 < value <= FLOAT_MAX:
        raise serializers.ValidationError(f"must be a finite number > 0, got {value}")


POSITIVE = {"validators": [finite_positive]}


class NewComparisonSerializer(serializers.ModelSerializer):
    template = serializers.ChoiceField(
        choices=list(protocols.TEMPLATES), required=False, allow_blank=True
    )

    class Meta:
        model = Comparison
        fields = [
            "code", "title", "description", "template", "submission_deadline",
            "assigned_value_method", "sigma_pt_mode", "sigma_pt_value", "en_limit",
            "enrolment_open", "enrolment_closes",
        ]  # fmt: skip
        extra_kwargs = {
            "sigma_pt_value": POSITIVE,
            "en_limit": POSITIVE,
            "code": {"error_messages": {"invalid": CODE_INVALID}},
        }
