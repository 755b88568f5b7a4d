"""Coordinator setup API: add devices, generate the point grid, invite laboratories,
accept every complete submission (docs/interfaces.md §3, extended; creating a comparison
is ``POST /api/v1/comparisons/``, labs.api.views.ComparisonList). Thin views over
``proficiency.services`` and ``labs.services``; the same rules as the coordinator pages."""

from __future__ import annotations

from typing import Any, cast

from django.contrib.auth.models import User
from django.shortcuts import get_object_or_404
from django.urls import path
from drf_spectacular.utils import extend_schema, extend_schema_field
from rest_framework import serializers, status
from rest_framework.request import Request
from rest_framework.response import Response

from common.api import valid_data
from common.errors import ValidationFailed
from common.quantities import DEFAULT as DEFAULT_QUANTITY
from common.quantities import NAMES as KIND_NAMES
from common.sizes import database_id
from labs.access import require_coordinator
from labs.api.serializers import ScopeSerializer
from labs.api.views import ApiView
from labs.models import Laboratory, Participant
from labs.review import submissions_accept_complete
from labs.selectors import participant_points, scope_text
from labs.services import Scope, participant_scope_set, participants_invite
from proficiency import protocols
from proficiency.models import Device
from proficiency.services import (
    DEVICE_FIELDS,
    comparison_apply_template,
    device_create,
    measurement_points_generate,
)


@extend_schema_field(
    {"type": "string", "minLength": 1, "maxLength": 80, "description": "e.g. MEMS 1"}
)
class _DeviceName(serializers.CharField):
    """The device name as the API documents it; checked by ``device_create``."""


class DeviceInSerializer(serializers.ModelSerializer):
    # the name's rule (stripped, required, length, unique) is proficiency.services.device_create's
    # required and at most 80 long in the schema, as before; a blank or long name is
    # refused by the service with the message the web page gives too
    name = _DeviceName(allow_blank=True, trim_whitespace=False)

    class Meta:
        model = Device
        fields = DEVICE_FIELDS
        validators: list[Any] = []


class DeviceAdd(ApiView):
    @extend_schema(request=DeviceInSerializer, responses={201: DeviceInSerializer})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        data = valid_data(DeviceInSerializer(data=request.data))
        device = device_create(comparison=access.comparison, name=data.pop("name", ""), **data)
        return Response(DeviceInSerializer(device).data, status=status.HTTP_201_CREATED)


class GridSerializer(serializers.Serializer):
    template = serializers.ChoiceField(choices=list(protocols.TEMPLATES), required=False)
    devices = serializers.ListField(child=serializers.CharField(), required=False)
    axes = serializers.ListField(child=serializers.CharField(max_length=1), required=False)
    frequencies_hz = serializers.ListField(child=serializers.FloatField(), required=False)
    benches = serializers.ListField(child=serializers.CharField(), required=False)
    directions = serializers.ListField(child=serializers.CharField(), required=False)
    quantities = serializers.ListField(
        child=serializers.CharField(), required=False,
        help_text=f"the quantity kinds of the points, of {', '.join(KIND_NAMES)} (default: "
        "magnitude); with a template, among those its benches offer",
    )  # fmt: skip


class PointsGenerate(ApiView):
    """The measurement-point grid from a seed template, or from lists (idempotent)."""

    @extend_schema(request=GridSerializer, responses={201: None})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        data = valid_data(GridSerializer(data=request.data))
        c = access.comparison
        devices = list(c.devices.filter(name__in=data["devices"]) if "devices" in data
                       else c.devices.all())  # fmt: skip
        if data.get("template"):
            new = comparison_apply_template(
                comparison=c, template_key=data["template"], devices=devices,
                quantities=data.get("quantities", [DEFAULT_QUANTITY]),
            )  # fmt: skip
        else:
            new = measurement_points_generate(
                comparison=c,
                devices=devices,
                axes=data.get("axes", ["X", "Y", "Z"]),
                frequencies_hz=data.get("frequencies_hz", []),
                benches=data.get("benches", []),
                directions=data.get("directions"),
                quantities=data.get("quantities", [DEFAULT_QUANTITY]),
            )
        body = {"created": len(new), "measurement_points": c.measurement_points.count()}
        return Response(body, status=status.HTTP_201_CREATED)


class ScopeOutSerializer(serializers.Serializer):
    participant = serializers.CharField()
    devices = serializers.ListField(child=serializers.CharField())
    benches = serializers.ListField(child=serializers.CharField())
    axes = serializers.ListField(child=serializers.CharField())
    frequencies_hz = serializers.ListField(child=serializers.FloatField())
    description = serializers.CharField()
    n_measurement_points = serializers.IntegerField()


def scope_body(participant: Participant) -> dict[str, Any]:
    return {
        "participant": participant.code,
        "devices": sorted(d.name for d in participant.scope_devices.all()),
        "benches": list(participant.scope_benches),
        "axes": list(participant.scope_axes),
        "frequencies_hz": list(participant.scope_frequencies_hz),
        "description": scope_text(participant),
        "n_measurement_points": participant_points(participant).count(),
    }


class InviteSerializer(serializers.Serializer):
    laboratories = serializers.ListField(child=serializers.CharField(), min_length=1)
    scope = ScopeSerializer(required=False)


class Invite(ApiView):
    """Invite laboratories by name or id; each gets a random anonymous code."""

    @extend_schema(request=InviteSerializer, responses={201: None})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        data = valid_data(InviteSerializer(data=request.data))
        wanted = data["laboratories"]
        scope = data.get("scope")
        ids = [i for i in map(database_id, wanted) if i is not None]
        labs = {str(lab.pk): lab for lab in Laboratory.objects.filter(pk__in=ids)} | {
            lab.name: lab for lab in Laboratory.objects.filter(name__in=wanted)
        }
        unknown = [w for w in wanted if w not in labs]
        if unknown:
            raise ValidationFailed(f"Unknown laboratories: {', '.join(unknown)}.")
        added = participants_invite(
            comparison=access.comparison,
            laboratories=[labs[w] for w in wanted],
            scope=None if scope is None else Scope(**scope),
        )
        body = {
            "participants": [
                {"laboratory": p.laboratory.name, "code": p.code, "scope": scope_body(p)}
                for p in added
            ]
        }
        return Response(body, status=status.HTTP_201_CREATED)


class ParticipantScope(ApiView):
    """A participant's scope: what it measures and reports (docs/domain.md §10). ``PUT``
    replaces it (absent lists: every value) until the submission deadline (409 after)."""

    def _participant(self, code: str) -> Participant:
        access = self.access(code)
        require_coordinator(access)
        return get_object_or_404(
            access.comparison.participants.select_related("comparison"),
            code=self.kwargs["participant"],
        )

    @extend_schema(responses={200: ScopeOutSerializer})
    def get(self, request: Request, code: str, participant: str) -> Response:
        return Response(scope_body(self._participant(code)))

    @extend_schema(request=ScopeSerializer, responses={200: ScopeOutSerializer})
    def put(self, request: Request, code: str, participant: str) -> Response:
        chosen = self._participant(code)
        scope = ScopeSerializer(data=request.data).scope()
        participant_scope_set(participant=chosen, scope=scope)
        return Response(scope_body(chosen))


class AcceptedSerializer(serializers.Serializer):
    accepted = serializers.ListField(child=serializers.CharField(), help_text="participant codes")
    count = serializers.IntegerField()


class AcceptComplete(ApiView):
    """Accept every participant's latest version that is submitted, undecided, complete for
    its scope and not asked to check (docs/lifecycles.md §2), in one transaction; each
    laboratory is told as by a single acceptance. None waiting: an empty list."""

    @extend_schema(request=None, responses={200: AcceptedSerializer})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        accepted = submissions_accept_complete(
            comparison=access.comparison,
            user=cast(User, request.user),  # a coordinator
        )
        codes = [s.participant.code for s in accepted]
        return Response({"accepted": codes, "count": len(codes)})


urlpatterns = [
    path("comparisons/<slug:code>/devices/", DeviceAdd.as_view(), name="device-add"),
    path(
        "comparisons/<slug:code>/measurands/generate/",
        PointsGenerate.as_view(),
        name="measurand-generate",
    ),
    path("comparisons/<slug:code>/participants/", Invite.as_view(), name="participant-invite"),
    path(
        "comparisons/<slug:code>/submissions/accept-complete/",
        AcceptComplete.as_view(),
        name="submission-accept-complete",
    ),
    path(
        "comparisons/<slug:code>/participants/<str:participant>/scope/",
        ParticipantScope.as_view(),
        name="participant-scope",
    ),
]
