"""Coordinator setup API: add devices, generate the point grid, invite laboratories
(docs/interfaces.md §3, extended; creating a comparison is ``POST /api/v1/comparisons/``,
labs.api.views.ComparisonList). Thin views over ``proficiency.services`` and
``labs.services``; the same rules as the coordinator pages."""

from __future__ import annotations

from typing import Any

from django.urls import path
from drf_spectacular.utils import extend_schema, extend_schema_field
from rest_framework import serializers, status
from rest_framework.request import Request
from rest_framework.response import Response

from common.api import valid_data
from common.errors import ValidationFailed
from labs.access import require_coordinator
from labs.api.views import ApiView
from labs.models import Laboratory
from labs.services import participants_invite
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
                comparison=c, template_key=data["template"], devices=devices
            )
        else:
            new = measurement_points_generate(
                comparison=c,
                devices=devices,
                axes=data.get("axes", ["X", "Y", "Z"]),
                frequencies_hz=data.get("frequencies_hz", []),
                benches=data.get("benches", []),
                directions=data.get("directions"),
            )
        body = {"created": len(new), "measurement_points": c.measurement_points.count()}
        return Response(body, status=status.HTTP_201_CREATED)


class InviteSerializer(serializers.Serializer):
    laboratories = serializers.ListField(child=serializers.CharField(), min_length=1)


class Invite(ApiView):
    """Invite laboratories by name or id; each gets a random anonymous code."""

    @extend_schema(request=InviteSerializer, responses={201: None})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        wanted = valid_data(InviteSerializer(data=request.data))["laboratories"]
        # ids are plain ASCII digits that fit a bigint ("¹".isdigit() is True in Python)
        ids = [int(w) for w in wanted if w.isascii() and w.isdigit() and len(w) <= 18]
        labs = {str(lab.pk): lab for lab in Laboratory.objects.filter(pk__in=ids)} | {
            lab.name: lab for lab in Laboratory.objects.filter(name__in=wanted)
        }
        unknown = [w for w in wanted if w not in labs]
        if unknown:
            raise ValidationFailed(f"Unknown laboratories: {', '.join(unknown)}.")
        added = participants_invite(
            comparison=access.comparison, laboratories=[labs[w] for w in wanted]
        )
        body = {"participants": [{"laboratory": p.laboratory.name, "code": p.code} for p in added]}
        return Response(body, status=status.HTTP_201_CREATED)


urlpatterns = [
    path("comparisons/<slug:code>/devices/", DeviceAdd.as_view(), name="device-add"),
    path(
        "comparisons/<slug:code>/measurands/generate/",
        PointsGenerate.as_view(),
        name="measurand-generate",
    ),
    path("comparisons/<slug:code>/participants/", Invite.as_view(), name="participant-invite"),
]
