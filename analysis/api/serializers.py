"""Serializers of the coordinator API: plain shapes, labs by participant code only."""

from __future__ import annotations

from typing import Any

import numpy as np
from django.urls import reverse
from drf_spectacular.utils import extend_schema_field
from rest_framework import serializers

from analysis.kit_results import covariance_of
from analysis.models import AnalysisRun, KitPointFit, Publication, Score
from analysis.selectors import z_used_name
from labs.models import Submission
from proficiency.models import AssignedValueMethod, Comparison, DriftTreatment, SigmaPtMode


class RunParameters(serializers.Serializer):
    """The settings a run computed with: the schema of ``parameters`` (the stored object is
    returned as it is; a run stored before a key existed lacks it)."""

    assigned_value_method = serializers.ChoiceField(
        choices=AssignedValueMethod.choices, required=False
    )
    sigma_pt_mode = serializers.ChoiceField(choices=SigmaPtMode.choices, required=False)
    sigma_pt_value = serializers.FloatField(allow_null=True, required=False)
    en_limit = serializers.FloatField(required=False)
    compare = serializers.ListField(
        child=serializers.CharField(),
        required=False,
        help_text="factors of the stored compatibility matrices",
    )
    drift_treatment = serializers.ChoiceField(
        choices=DriftTreatment.choices, required=False,
        help_text="what a drifting kit did to the scores: correct (each result corrected to "
        "the mean date of the pilot's repeats) or u_stab (its u_stab added)",
    )  # fmt: skip


@extend_schema_field(RunParameters)
class _RunParameters(serializers.JSONField):
    pass


class AnalysisRunSerializer(serializers.ModelSerializer):
    comparison = serializers.CharField(source="comparison.code")
    parameters = _RunParameters(read_only=True)

    class Meta:
        model = AnalysisRun
        fields = [
            "id", "comparison", "status", "progress", "stage", "error", "parameters",
            "code_version", "created_at", "started_at", "finished_at",
        ]  # fmt: skip
        read_only_fields = fields


def _kit_number(help_text: str) -> serializers.FloatField:
    """A number of a round with kits (docs/domain.md §13, §14): read only, null elsewhere."""
    return serializers.FloatField(
        read_only=True, allow_null=True, default=None, help_text=help_text
    )


class ScoreSerializer(serializers.ModelSerializer):
    lab = serializers.CharField(source="result.submission.participant.code")
    device = serializers.CharField(source="result.measurement_point.device.name")
    axis = serializers.CharField(source="result.measurement_point.axis")
    frequency_hz = serializers.FloatField(source="result.measurement_point.frequency_hz")
    bench = serializers.CharField(source="result.measurement_point.bench")
    direction = serializers.CharField(source="result.measurement_point.direction")
    quantity = serializers.CharField(source="result.measurement_point.quantity")
    value = serializers.FloatField(source="result.value")
    expanded_uncertainty = serializers.FloatField(source="result.expanded_uncertainty")
    z_used = serializers.SerializerMethodField(
        help_text="the z score that counts and that z_flag is of: z, z_prime (where u(x_pt) > "
        "0.3 σ_pt, ISO 13528 9.5), or null without σ_pt"
    )

    # a round with kits (docs/domain.md §13, §14); null elsewhere
    kit = serializers.CharField(
        read_only=True,
        allow_null=True,
        default=None,
        help_text="the kit the result was measured on",
    )
    linked_d = _kit_number("d against the one reference across the kits")
    linked_expanded_uncertainty = _kit_number("U(d) = 2·u(d)")
    u_link = _kit_number("the part of u(d) that is not the lab's own")
    drift_correction = _kit_number(
        "added to the value for a drifting kit: −b·(t − t̄); 0 where none"
    )
    u_drift = _kit_number(
        "standard uncertainty added for a drifting kit: |t − t̄|·u(b) or u_stab(t)"
    )

    def get_z_used(self, score: Score) -> str | None:
        return z_used_name(score)

    class Meta:
        model = Score
        fields = [
            "lab", "device", "axis", "frequency_hz", "bench", "direction", "quantity", "value",
            "expanded_uncertainty", "d", "d_percent", "en", "zeta", "z", "z_prime", "flag",
            "z_flag", "correlation_applied", "correlation_failed", "in_assigned_value", "z_used",
            "kit", "linked_d", "linked_expanded_uncertainty", "u_link", "drift_correction",
            "u_drift",
        ]  # fmt: skip


class MatrixSerializer(serializers.Serializer):
    """Documentation shape of one compatibility matrix (docs/interfaces.md §4 keys)."""

    factor = serializers.CharField()
    group = serializers.DictField()
    levels = serializers.ListField()
    value = serializers.ListField(child=serializers.FloatField())
    expanded_uncertainty = serializers.ListField(child=serializers.FloatField())
    en = serializers.ListField(child=serializers.ListField(child=serializers.FloatField()))
    incompatible_pairs = serializers.IntegerField()


class DoeCovarianceSerializer(serializers.Serializer):
    """The covariance of the linked degrees of equivalence at one point (docs/domain.md
    §14): ``codes`` in order, the n × n ``covariance`` and ``correlation`` (null where a
    u(d) is 0), full precision; from a ``KitPointFit``."""

    device = serializers.CharField(source="measurement_point.device.name")
    axis = serializers.CharField(source="measurement_point.axis")
    frequency_hz = serializers.FloatField(source="measurement_point.frequency_hz")
    bench = serializers.CharField(source="measurement_point.bench")
    direction = serializers.CharField(source="measurement_point.direction")
    quantity = serializers.CharField(source="measurement_point.quantity")
    reference = serializers.CharField(help_text="pilot or weighted_mean")
    codes = serializers.ListField(child=serializers.CharField(), read_only=True)
    covariance = serializers.ListField(
        child=serializers.ListField(child=serializers.FloatField()), read_only=True,
        help_text="cov(d_a, d_b), in the order of codes; the diagonal is u²(d)",
    )  # fmt: skip
    correlation = serializers.ListField(
        child=serializers.ListField(child=serializers.FloatField(allow_null=True)),
        read_only=True, help_text="r = cov(d_a, d_b)/(u(d_a)·u(d_b)); null where undefined",
    )  # fmt: skip

    def to_representation(self, instance: KitPointFit) -> dict[str, Any]:
        data = super().to_representation(instance)
        c = covariance_of(instance)
        codes, cov = (c.codes, c.covariance) if c is not None else ([], np.zeros((0, 0)))
        r = c.correlation if c is not None else cov
        data["codes"] = codes
        data["covariance"] = cov.tolist()
        data["correlation"] = [[x if np.isfinite(x) else None for x in row] for row in r.tolist()]
        return data


class ComparisonStateSerializer(serializers.ModelSerializer):
    class Meta:
        model = Comparison
        fields = ["code", "status", "submission_deadline"]
        read_only_fields = fields


class PublicationSerializer(serializers.ModelSerializer):
    comparison = serializers.CharField(source="comparison.code")
    url = serializers.SerializerMethodField(help_text="this job in the API")

    class Meta:
        model = Publication
        fields = [
            "id", "url", "comparison", "run", "status", "progress", "stage", "error",
            "report_ids", "created_at", "started_at", "finished_at",
        ]  # fmt: skip
        read_only_fields = fields

    def get_url(self, job: Publication) -> str:
        path = reverse("publication-detail", args=[job.pk])
        request = self.context.get("request")
        return request.build_absolute_uri(path) if request is not None else path


class PublishAnswerSerializer(ComparisonStateSerializer):
    """The answer of ``publish``: the comparison's keys and its ``publication`` job."""

    publication = PublicationSerializer(read_only=True)

    class Meta(ComparisonStateSerializer.Meta):
        fields = [*ComparisonStateSerializer.Meta.fields, "publication"]
        read_only_fields = fields


class DecisionResultSerializer(serializers.ModelSerializer):
    participant = serializers.CharField(source="participant.code")

    class Meta:
        model = Submission
        fields = ["participant", "version", "status", "message", "decided_at"]
        read_only_fields = fields
