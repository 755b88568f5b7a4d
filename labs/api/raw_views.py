"""``/api/v1/comparisons/{code}/raw-data/``: raw records behind a result.

A participant uploads and lists its own records; a coordinator lists every
participant's (by code); another laboratory's record is 404.
"""

from __future__ import annotations

from typing import Any, cast

from django.conf import settings
from django.db.models import QuerySet
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import generics
from rest_framework.request import Request
from rest_framework.response import Response

from common.parsers import FormParser, MultiPartParser
from labs.access import ComparisonAccess, caller_of, require_participant
from labs.api import raw_serializers as rs
from labs.api.views import AUTH_ERRORS, CODE, NOT_VISIBLE, SUBMIT_ERRORS, ApiView, validated
from labs.api.views import check_content_length as _check_content_length
from labs.models import RawRecord
from labs.raw import RawUploadLimit
from labs.raw_selectors import raw_record_get, raw_records_of, raw_records_of_comparison
from labs.raw_services import raw_request_limit, raw_upload_submit


def raw_records_in_scope(access: ComparisonAccess) -> QuerySet[RawRecord]:
    """Coordinators: every participant's records; participants: their own."""
    if access.is_coordinator:
        return raw_records_of_comparison(access.comparison.pk)
    assert access.participant is not None  # comparison_access grants one of the two roles
    return raw_records_of(access.participant)


class RawDataCollection(ApiView, generics.ListAPIView):
    """Your laboratory's raw records (coordinators: every participant's, by code)."""

    serializer_class = rs.RawRecordSerializer
    filter_backends: list[type] = []
    parser_classes = [MultiPartParser, FormParser]

    def get_queryset(self) -> QuerySet[Any]:
        if getattr(self, "swagger_fake_view", False):
            return RawRecord.objects.none()
        return raw_records_in_scope(self.access(self.kwargs["code"]))

    def initial(self, request: Request, *args: Any, **kwargs: Any) -> None:
        if request.method == "POST":  # before anything (CSRF, auth) reads the body
            _check_content_length(request, raw_request_limit(), "upload")
            limit = RawUploadLimit(request._request, limit=settings.RAW_UPLOAD_MAX_BYTES)
            # a plain list until the body is read; RawUploadLimit is duck-typed
            cast(list[Any], request._request.upload_handlers).insert(0, limit)
        super().initial(request, *args, **kwargs)

    @extend_schema(
        tags=["raw data"],
        parameters=[CODE],
        responses={200: rs.RawRecordSerializer, **AUTH_ERRORS, **NOT_VISIBLE},
    )
    def get(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        return super().get(request, *args, **kwargs)

    @extend_schema(
        tags=["raw data"],
        parameters=[CODE],
        request={"multipart/form-data": rs.RawUploadRequestSerializer},
        responses={201: rs.RawRecordSerializer, **SUBMIT_ERRORS, **AUTH_ERRORS, **NOT_VISIBLE},
    )
    def post(self, request: Request, code: str) -> Response:
        """Attach raw record(s) to a point of your current submission; the sensitivity is
        recomputed in the background (`recomputation.status`)."""
        participant = require_participant(self.access(code))
        data = validated(rs.RawUploadRequestSerializer, request.data)
        record = raw_upload_submit(
            participant=participant,
            point_fields=data,
            file=data["file"],
            sidecar=data.get("sidecar"),
            meta_fields=data,
            reference_file=data.get("reference_file"),
            reference_sidecar=data.get("reference_sidecar"),
            reference_fields=rs.reference_fields(data),
            user=caller_of(request).user,
        )
        record = raw_record_get(raw_records_of(participant), record.pk)
        return Response(rs.RawRecordSerializer(record).data, status=201)


@extend_schema(
    tags=["raw data"],
    parameters=[CODE, OpenApiParameter("pk", int, OpenApiParameter.PATH)],
    responses={200: rs.RawRecordSerializer, **AUTH_ERRORS, **NOT_VISIBLE},
)
class RawDataDetail(ApiView):
    """One raw record with its recomputation (reported vs recomputed, En, budget)."""

    def get(self, request: Request, code: str, pk: int) -> Response:
        record = raw_record_get(raw_records_in_scope(self.access(code)), pk)
        return Response(rs.RawRecordSerializer(record).data)
