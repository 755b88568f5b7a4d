"""Serializers of the comparison domain shared by the API modules."""

from __future__ import annotations

from rest_framework import serializers

from proficiency import protocols
from proficiency.models import Comparison


class NewComparisonSerializer(serializers.ModelSerializer):
    template = serializers.ChoiceField(
        choices=list(protocols.TEMPLATES), required=False, allow_blank=True
    )

    class Meta:
        model = Comparison
        fields = [
            "code", "title", "description", "template", "submission_deadline",
            "assigned_value_method", "sigma_pt_mode", "sigma_pt_value", "en_limit",
        ]  # fmt: skip
