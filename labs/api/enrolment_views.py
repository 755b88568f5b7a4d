"""Calls for participation and applications (docs/interfaces.md §3, docs/lifecycles.md §7):
the open calls, a laboratory's application to one, and the coordinator's decision. Thin
views over ``labs.enrolment``; who may do what is ``labs.access``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from django.db.models import QuerySet
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import generics, serializers, status
from rest_framework.exceptions import PermissionDenied
from rest_framework.request import Request
from rest_framework.response import Response

from common.api import valid_data
from labs.access import (
    application_in_scope,
    applications_in_scope,
    applying_laboratory,
    call_access,
    caller_of,
)
from labs.api.serializers import ScopeSerializer
from labs.api.views import AUTH_ERRORS, CODE, NOT_VISIBLE, ApiView, _error
from labs.enrolment import NOTE_MAX_CHARS, enrolment_accept, enrolment_apply, enrolment_decline
from labs.models import Enrolment
from labs.selectors import scope_text
from labs.services import Scope
from proficiency.models import Comparison
from proficiency.selectors import call_levels, open_calls

# --- shapes ----------------------------------------------------------------------------------


class CallSerializer(serializers.Serializer):
    code = serializers.CharField()
    title = serializers.CharField()
    description = serializers.CharField()
    protocol = serializers.CharField()
    status = serializers.CharField()
    submission_deadline = serializers.DateTimeField(allow_null=True)
    enrolment_closes = serializers.DateTimeField(allow_null=True)
    devices = serializers.ListField(child=serializers.CharField())
    benches = serializers.ListField(child=serializers.CharField())
    axes = serializers.ListField(child=serializers.CharField())
    frequencies_hz = serializers.ListField(child=serializers.FloatField())
    n_measurement_points = serializers.IntegerField()


class ApplicationScopeSerializer(serializers.Serializer):
    devices = serializers.ListField(child=serializers.CharField())
    benches = serializers.ListField(child=serializers.CharField())
    axes = serializers.ListField(child=serializers.CharField())
    frequencies_hz = serializers.ListField(child=serializers.FloatField())
    description = serializers.CharField()


class ApplicationSerializer(serializers.Serializer):
    id = serializers.IntegerField()
    comparison = serializers.CharField()
    laboratory = serializers.CharField(help_text="The applying laboratory's name")
    status = serializers.ChoiceField(choices=Enrolment.Status.choices)
    scope = ApplicationScopeSerializer(help_text="The scope asked for")
    note = serializers.CharField()
    reason = serializers.CharField(help_text="The coordinator's reason for declining")
    participant = serializers.CharField(
        allow_null=True, help_text="The participant code, once accepted"
    )
    created_at = serializers.DateTimeField()
    decided_at = serializers.DateTimeField(allow_null=True)


class ApplyRequestSerializer(serializers.Serializer):
    scope = ScopeSerializer(required=False)
    note = serializers.CharField(
        required=False, allow_blank=True, default="", max_length=NOTE_MAX_CHARS
    )
    laboratory = serializers.IntegerField(
        required=False, help_text="The laboratory's id, for a person who manages several"
    )


class AcceptRequestSerializer(serializers.Serializer):
    scope = ScopeSerializer(required=False, help_text="The scope granted, if not the one asked for")


class DeclineRequestSerializer(serializers.Serializer):
    reason = serializers.CharField(allow_blank=True, trim_whitespace=False)


def call_body(comparison: Comparison, levels: Any) -> dict[str, Any]:
    return {
        "code": comparison.code,
        "title": comparison.title,
        "description": comparison.description,
        "protocol": comparison.protocol,
        "status": comparison.status,
        "submission_deadline": comparison.submission_deadline,
        "enrolment_closes": comparison.enrolment_closes,
        "devices": sorted(d.name for d in comparison.devices.all()),
        "benches": levels.benches,
        "axes": levels.axes,
        "frequencies_hz": levels.frequencies_hz,
        "n_measurement_points": levels.n_points,
    }


def application_body(application: Enrolment) -> dict[str, Any]:
    participant = application.participant
    return {
        "id": application.pk,
        "comparison": application.comparison.code,
        "laboratory": application.laboratory.name,
        "status": application.status,
        "scope": {
            "devices": sorted(d.name for d in application.scope_devices.all()),
            "benches": list(application.scope_benches),
            "axes": list(application.scope_axes),
            "frequencies_hz": list(application.scope_frequencies_hz),
            "description": scope_text(application),
        },
        "note": application.note,
        "reason": application.reason,
        "participant": participant.code if participant is not None else None,
        "created_at": application.created_at,
        "decided_at": application.decided_at,
    }


def _answer(application: Enrolment, code: int = status.HTTP_200_OK) -> Response:
    data = ApplicationSerializer(application_body(application)).data
    return Response(data, status=code)


APPLY_ERRORS = {
    400: _error("The scope does not fit the round (`errors` names each value) or the note"),
    403: _error("Only a manager of the laboratory (or its API key) applies"),
    409: _error("The call is not open, or the laboratory takes part or applied already"),
}
DECIDE_ERRORS = {
    403: _error("Only a coordinator of the round decides"),
    409: _error("The application is not pending, or the laboratory takes part already"),
}
APPLICATION = OpenApiParameter("id", OpenApiTypes.INT, OpenApiParameter.PATH)

# --- views -----------------------------------------------------------------------------------


class _List(ApiView, generics.ListAPIView):
    """A list paginated as every list of the API (``?page=N``, 100 a page), each row made
    by :meth:`body` (the schema documents ``serializer_class`` in the page)."""

    filter_backends: list[type] = []

    def body(self, row: Any) -> dict[str, Any]:
        raise NotImplementedError

    def rows(self) -> QuerySet[Any]:
        raise NotImplementedError

    def get_queryset(self) -> QuerySet[Any]:
        if getattr(self, "swagger_fake_view", False):  # schema generation: no request
            return self.rows().none()
        return self.rows()

    def list(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        page = self.paginate_queryset(self.get_queryset())
        assert page is not None  # the API's lists are always paginated (settings)
        return self.get_paginated_response(self.page_body(page))

    def page_body(self, page: Sequence[Any]) -> Sequence[dict[str, Any]]:
        serializer = self.get_serializer_class()
        return [serializer(self.body(row)).data for row in page]


@extend_schema(tags=["enrolment"], responses={200: CallSerializer, **AUTH_ERRORS})
class CallList(_List):
    """The rounds taking applications now: their devices, benches, axes and frequencies (what
    a scope may ask for), the deadline and when the enrolment closes."""

    serializer_class = CallSerializer

    def rows(self) -> QuerySet[Any]:
        return open_calls()

    def page_body(self, page: Sequence[Any]) -> Sequence[dict[str, Any]]:
        levels = call_levels(page)  # one query for the page's rounds
        return [CallSerializer(call_body(c, levels[c.pk])).data for c in page]


class ApplicationCollection(_List):
    """A round's applications: the coordinators see all, a laboratory its own."""

    serializer_class = ApplicationSerializer

    def rows(self) -> QuerySet[Any]:
        if getattr(self, "swagger_fake_view", False):
            return Enrolment.objects.none()
        return applications_in_scope(call_access(caller_of(self.request), self.kwargs["code"]))

    def body(self, row: Any) -> dict[str, Any]:
        return application_body(row)

    @extend_schema(
        tags=["enrolment"],
        parameters=[CODE],
        responses={200: ApplicationSerializer, **AUTH_ERRORS, **NOT_VISIBLE},
    )
    def get(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        return super().get(request, *args, **kwargs)

    @extend_schema(
        tags=["enrolment"],
        parameters=[CODE],
        request=ApplyRequestSerializer,
        responses={201: ApplicationSerializer, **APPLY_ERRORS, **AUTH_ERRORS, **NOT_VISIBLE},
    )
    def post(self, request: Request, code: str) -> Response:
        """Apply to the round with the scope the laboratory measures (absent: every point)."""
        caller = caller_of(request)
        access = call_access(caller, code)
        data = valid_data(ApplyRequestSerializer(data=request.data))
        laboratory = applying_laboratory(caller, data.get("laboratory"))
        application = enrolment_apply(
            comparison=access.comparison, laboratory=laboratory, scope=_scope(data),
            note=data["note"], user=caller.user,
        )  # fmt: skip
        return _answer(application, status.HTTP_201_CREATED)


def _scope(data: dict[str, Any]) -> Scope:
    given = data.get("scope") or {}
    return Scope(
        devices=given.get("devices", []), benches=given.get("benches", []),
        axes=given.get("axes", []), frequencies_hz=given.get("frequencies_hz", []),
    )  # fmt: skip


class _Decision(ApiView):
    def application(self, request: Request, code: str, pk: int) -> Enrolment:
        """The application if the caller sees it (404 otherwise); 403 unless a coordinator."""
        access = call_access(caller_of(request), code)
        application = application_in_scope(access, pk)
        if not access.is_coordinator:
            raise PermissionDenied(f"Only a coordinator of {code} can decide an application.")
        return application


class ApplicationAccept(_Decision):
    @extend_schema(
        tags=["enrolment"],
        parameters=[CODE, APPLICATION],
        request=AcceptRequestSerializer,
        responses={201: ApplicationSerializer, **DECIDE_ERRORS, **AUTH_ERRORS, **NOT_VISIBLE},
    )
    def post(self, request: Request, code: str, pk: int) -> Response:
        """Accept: the laboratory becomes a participant with a random code and the scope
        asked for (or `scope`, as amended), and is sent the invitation."""
        application = self.application(request, code, pk)
        data = valid_data(AcceptRequestSerializer(data=request.data))
        scope = _scope(data) if "scope" in data else None
        accepted = enrolment_accept(enrolment=application, user=caller_of(request).user,
                                    scope=scope)  # fmt: skip
        return _answer(accepted, status.HTTP_201_CREATED)


class ApplicationDecline(_Decision):
    @extend_schema(
        tags=["enrolment"],
        parameters=[CODE, APPLICATION],
        request=DeclineRequestSerializer,
        responses={200: ApplicationSerializer, **DECIDE_ERRORS, **AUTH_ERRORS, **NOT_VISIBLE},
    )
    def post(self, request: Request, code: str, pk: int) -> Response:
        """Decline with a reason (required), which the laboratory is sent."""
        application = self.application(request, code, pk)
        data = valid_data(DeclineRequestSerializer(data=request.data))
        declined = enrolment_decline(
            enrolment=application, user=caller_of(request).user, reason=data["reason"]
        )
        return _answer(declined)
