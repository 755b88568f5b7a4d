"""API views (docs/interfaces.md §3): validate input, call one service or selector, serialise.

Errors are raised, never built here: ApplicationError subclasses and DRF's own
exceptions are turned into ``{"detail", "errors"}`` by
:func:`common.errors.api_exception_handler`.
"""

from __future__ import annotations

from typing import Any, cast

import django_filters
from django.conf import settings
from django.contrib.auth.models import User
from django.db.models import QuerySet
from django.urls import reverse
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, OpenApiResponse, extend_schema
from rest_framework import serializers, status
from rest_framework.authentication import SessionAuthentication
from rest_framework.exceptions import PermissionDenied
from rest_framework.permissions import AllowAny, IsAuthenticated
from rest_framework.renderers import BaseRenderer, JSONRenderer
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.throttling import AnonRateThrottle
from rest_framework.views import APIView

from common.api import ValuesListView, valid_data
from common.errors import RequestTooLarge, ValidationFailed
from common.parsers import FormParser, JSONParser, MultiPartParser
from common.rendering import ValuesRendering
from labs.access import (
    ComparisonAccess,
    caller_of,
    comparison_access,
    comparisons_for,
    measurement_points,
    require_participant,
    submission_in_scope,
    submission_results,
    submissions_in_scope,
)
from labs.api import serializers as s
from labs.api.authentication import LabAPIKeyAuthentication
from labs.api.throttling import LabAPIKeyRateThrottle, SessionUserRateThrottle
from labs.importers.values import human_size
from labs.models import Submission
from labs.selectors import point_unit_expression, results_template, scope_flag
from labs.services import submission_from_file, submission_from_records
from proficiency.models import Comparison, ComparisonStatus, MeasurementPoint
from proficiency.serializers import NewComparisonSerializer
from proficiency.services import comparison_create

#: multipart framing (boundaries, part headers, the submit field) on top of the file itself
MULTIPART_SLACK_BYTES = 64 * 1024


def _error(description: str) -> OpenApiResponse:
    return OpenApiResponse(s.ErrorSerializer, description=description)


AUTH_ERRORS = {
    401: _error("No credentials, or an invalid, revoked or expired API key"),
    429: _error("Too many requests; retry after the Retry-After header's seconds"),
}
NOT_VISIBLE = {404: _error("No such comparison, or not visible to you (also other labs')")}
SUBMIT_ERRORS = {
    400: _error(
        "The results were refused; `errors` lists the bad rows and fields (the first 1,000, "
        "then one entry without row or field counting the rest)"
    ),
    403: _error("You coordinate this comparison but are not a participant"),
    409: _error("The comparison is not open, or its deadline has passed"),
    413: _error("The request body or the file is too large"),
    422: _error("The Idempotency-Key was already used for another request"),
}
CODE = OpenApiParameter(
    "code", OpenApiTypes.STR, OpenApiParameter.PATH, description="Comparison code"
)
IDEMPOTENCY_KEY = OpenApiParameter(
    "Idempotency-Key",
    OpenApiTypes.STR,
    OpenApiParameter.HEADER,
    required=False,
    description=(
        "Optional, 1-255 printable ASCII characters, unique per request (e.g. a UUID): "
        "a retry with the same key answers the version the first request stored (201, "
        "same body, header `Idempotent-Replayed: true`); the same key with other results "
        "or another `submit` answers 422. Keys are kept IDEMPOTENCY_KEY_HOURS (24 h)."
    ),
)
MAX_KEY_LENGTH = 255
REPLAYED = {"Idempotent-Replayed": "true"}


def idempotency_key(request: Request) -> str:
    """The request's ``Idempotency-Key`` header ("" when absent), or a 400 naming it."""
    key = request.headers.get("Idempotency-Key")
    if key is None:
        return ""
    key = key.strip()
    if not 1 <= len(key) <= MAX_KEY_LENGTH or not all(" " < c <= "~" for c in key):
        raise ValidationFailed(
            f"The Idempotency-Key header must be 1 to {MAX_KEY_LENGTH} printable ASCII "
            f"characters without spaces (got {len(key)} characters).",
            errors=[{"field": "Idempotency-Key", "message": "not a valid key"}],
        )
    return key


def submission_answer(submission: Submission) -> Response:
    """201 with the version; a retry answered by the version already stored says so."""
    headers = REPLAYED if getattr(submission, "replayed", False) else None
    return Response(s.SubmissionSerializer(submission).data, status=201, headers=headers)


def validated(serializer_class: type[serializers.Serializer], data: Any) -> dict[str, Any]:
    serializer = serializer_class(data=data)
    if not serializer.is_valid():
        raise ValidationFailed(
            "The request is not valid.", errors=s.as_row_errors(serializer.errors)
        )
    return serializer.validated_data


def check_content_length(request: Request, limit: int, what: str) -> None:
    """413 on the declared size alone, before anything reads the body."""
    try:
        length = int(request.META.get("CONTENT_LENGTH") or 0)
    except ValueError:
        length = 0
    if length > limit:
        raise RequestTooLarge(
            f"The {what} is {human_size(length)}; the limit is {human_size(limit)}. "
            "Split the results into several drafts, or contact the coordinator."
        )


class ApiView(APIView):
    authentication_classes = [LabAPIKeyAuthentication, SessionAuthentication]
    permission_classes = [IsAuthenticated]
    throttle_classes = [LabAPIKeyRateThrottle, SessionUserRateThrottle]

    def access(self, code: str) -> ComparisonAccess:
        return comparison_access(caller_of(self.request), code)


class ApiRoot(ApiView):
    """``GET /api/v1/``: where the documentation and the schema are; open to everyone (no
    data), throttled like every API view (anonymous callers by address)."""

    permission_classes = [AllowAny]
    throttle_classes = [*ApiView.throttle_classes, AnonRateThrottle]

    @extend_schema(tags=["about"], responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request) -> Response:
        return Response(
            {
                "version": "v1",
                "docs": request.build_absolute_uri(reverse("api-docs")),
                "schema": request.build_absolute_uri(reverse("schema")),
            }
        )


class ComparisonFilter(django_filters.FilterSet):
    status = django_filters.ChoiceFilter(choices=ComparisonStatus.choices)


@extend_schema(tags=["comparisons"], responses={200: s.ComparisonSerializer, **AUTH_ERRORS})
class ComparisonList(ApiView, ValuesListView):
    """Comparisons visible to you: your laboratory's, the ones you coordinate (all for admins)."""

    serializer_class = s.ComparisonSerializer
    rendering = ValuesRendering(s.ComparisonSerializer)
    filterset_class = ComparisonFilter

    def get_queryset(self) -> QuerySet[Any]:
        return comparisons_for(caller_of(self.request)).order_by("-created_at", "code")

    @extend_schema(request=NewComparisonSerializer, responses={201: NewComparisonSerializer})
    def post(self, request: Request) -> Response:
        """Create a draft comparison (coordinators); the caller becomes its coordinator."""
        user = request.user
        if not getattr(user, "has_perm", None) or not user.has_perm("proficiency.add_comparison"):
            raise PermissionDenied("Only coordinators may create comparisons.")
        data = valid_data(NewComparisonSerializer(data=request.data))
        template = data.pop("template", "") or None
        # has_perm passed: a person (keys have no permissions)
        created = comparison_create(
            comparison=Comparison(**data), template_key=template, user=cast(User, user)
        )
        return Response(NewComparisonSerializer(created).data, status=status.HTTP_201_CREATED)


@extend_schema(
    tags=["comparisons"],
    parameters=[CODE],
    responses={200: s.ComparisonDetailSerializer, **AUTH_ERRORS, **NOT_VISIBLE},
)
class ComparisonDetail(ApiView):
    """Protocol, deadline, status and devices; `participant_code` is your own code."""

    def get(self, request: Request, code: str) -> Response:
        access = self.access(code)
        return Response(s.comparison_detail_data(access.comparison, access))


@extend_schema(
    tags=["comparisons"],
    parameters=[CODE],
    responses={200: s.MeasurementPointSerializer, **AUTH_ERRORS, **NOT_VISIBLE},
)
class MeasurandList(ApiView, ValuesListView):
    """The comparison's measurement points; a participant reports a result for each point
    whose `in_scope` is true (every point when it has no scope)."""

    serializer_class = s.MeasurementPointSerializer
    rendering = ValuesRendering(
        s.MeasurementPointSerializer, annotations={"in_scope": "in_scope", "unit": "point_unit"}
    )
    filter_backends: list[type] = []

    def get_queryset(self) -> QuerySet[Any]:
        if getattr(self, "swagger_fake_view", False):  # schema generation: no request
            return MeasurementPoint.objects.none()
        access = self.access(self.kwargs["code"])
        points = measurement_points(access.comparison)
        return points.annotate(
            in_scope=scope_flag(access.participant), point_unit=point_unit_expression()
        )


class CSVRenderer(BaseRenderer):
    media_type = "text/csv"
    format = "csv"
    charset = "utf-8"

    def render(
        self, data: Any, accepted_media_type: str | None = None, renderer_context: Any = None
    ) -> bytes:
        return data


class XLSXRenderer(CSVRenderer):
    media_type = "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet"
    format = "xlsx"
    charset = None  # type: ignore[assignment]


@extend_schema(
    tags=["comparisons"],
    parameters=[
        CODE,
        OpenApiParameter("format", OpenApiTypes.STR, enum=["csv", "xlsx"], default="csv"),
    ],
    responses={
        (200, "text/csv"): OpenApiTypes.BINARY,
        (200, XLSXRenderer.media_type): OpenApiTypes.BINARY,
        **AUTH_ERRORS,
        **NOT_VISIBLE,
    },
)
class ResultsTemplate(ApiView):
    """The results table (docs/interfaces.md §1) pre-filled with the measurement points (a
    participant's: those of its scope); fill in `sensitivity` and `expanded_uncertainty` and
    upload it."""

    renderer_classes = [CSVRenderer, XLSXRenderer]

    def get(self, request: Request, code: str) -> Response:
        access = self.access(code)
        comparison = access.comparison
        fmt = request.accepted_renderer.format
        # a participant's template lists its scope's points; a coordinator's, every point
        body = results_template(comparison, format=fmt, participant=access.participant)
        filename = f"{comparison.code}-results-template.{fmt}"
        return Response(body, headers={"Content-Disposition": f'attachment; filename="{filename}"'})

    def finalize_response(self, request: Request, response: Any, *args: Any, **kwargs: Any) -> Any:
        if response.status_code >= 400:  # errors stay JSON whatever format was asked
            request.accepted_renderer, request.accepted_media_type = (
                JSONRenderer(),
                "application/json",
            )
        return super().finalize_response(request, response, *args, **kwargs)


class SubmissionFilter(django_filters.FilterSet):
    status = django_filters.ChoiceFilter(choices=Submission.Status.choices)
    participant = django_filters.CharFilter(
        field_name="participant__code", help_text="Participant code"
    )


class SubmissionCollection(ApiView, ValuesListView):
    """Your laboratory's versions (coordinators: every participant's, by code)."""

    serializer_class = s.SubmissionSerializer
    rendering = ValuesRendering(s.SubmissionSerializer, annotations={"n_results": "n_results"})
    filterset_class = SubmissionFilter
    parser_classes = [JSONParser]
    # the rows go through the importer, which names row and column of a control character
    validates_control_characters = ("results",)

    def get_queryset(self) -> QuerySet[Any]:
        if getattr(self, "swagger_fake_view", False):
            return Submission.objects.none()
        return submissions_in_scope(self.access(self.kwargs["code"]))

    @extend_schema(
        tags=["submissions"],
        parameters=[CODE],
        responses={200: s.SubmissionSerializer, **AUTH_ERRORS, **NOT_VISIBLE},
    )
    def get(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        return super().get(request, *args, **kwargs)

    def initial(self, request: Request, *args: Any, **kwargs: Any) -> None:
        if request.method == "POST":
            check_content_length(request, settings.DATA_UPLOAD_MAX_MEMORY_SIZE, "request body")
        super().initial(request, *args, **kwargs)

    @extend_schema(
        tags=["submissions"],
        parameters=[CODE, IDEMPOTENCY_KEY],
        request=s.SubmissionRequestSerializer,
        responses={201: s.SubmissionSerializer, **SUBMIT_ERRORS, **AUTH_ERRORS, **NOT_VISIBLE},
    )
    def post(self, request: Request, code: str) -> Response:
        """Submit results as JSON rows (all or nothing); returns the new or updated version."""
        participant = require_participant(self.access(code))
        key = idempotency_key(request)
        data = validated(s.SubmissionRequestSerializer, request.data)
        submission = submission_from_records(
            participant=participant,
            records=data["results"],
            source=Submission.Source.API,
            user=caller_of(request).user,
            submit=data["submit"],
            idempotency_key=key,
        )
        return submission_answer(submission)


@extend_schema(
    tags=["submissions"],
    parameters=[CODE, IDEMPOTENCY_KEY],
    request={"multipart/form-data": s.UploadRequestSerializer},
    responses={201: s.SubmissionSerializer, **SUBMIT_ERRORS, **AUTH_ERRORS, **NOT_VISIBLE},
)
class SubmissionUpload(ApiView):
    """Submit a results file (CSV or XLSX, docs/interfaces.md §1), same rules as JSON."""

    parser_classes = [MultiPartParser, FormParser]

    def initial(self, request: Request, *args: Any, **kwargs: Any) -> None:
        limit = settings.MAX_UPLOAD_BYTES + MULTIPART_SLACK_BYTES
        check_content_length(request, limit, "upload")
        super().initial(request, *args, **kwargs)

    def post(self, request: Request, code: str) -> Response:
        participant = require_participant(self.access(code))
        key = idempotency_key(request)
        data = validated(s.UploadRequestSerializer, request.data)
        upload = data["file"]
        if upload.size > settings.MAX_UPLOAD_BYTES:
            raise RequestTooLarge(
                f"The file is {human_size(upload.size)}; the limit is "
                f"{human_size(settings.MAX_UPLOAD_BYTES)}."
            )
        submission = submission_from_file(
            participant=participant,
            data=upload.read(),
            filename=upload.name,
            user=caller_of(request).user,
            submit=data["submit"],
            idempotency_key=key,
        )
        return submission_answer(submission)


@extend_schema(
    tags=["submissions"],
    parameters=[
        CODE,
        OpenApiParameter("version", OpenApiTypes.INT, OpenApiParameter.PATH),
        OpenApiParameter(
            "participant",
            OpenApiTypes.STR,
            description="Participant code; required for coordinators, optional for participants",
        ),
    ],
    responses={
        200: s.SubmissionDetailSerializer,
        400: _error("?participant is missing"),
        **AUTH_ERRORS,
        **NOT_VISIBLE,
    },
)
class SubmissionDetail(ApiView):
    """One version with its results."""

    def get(self, request: Request, code: str, version: int) -> Response:
        submission = submission_in_scope(
            self.access(code),
            version=version,
            participant_code=request.query_params.get("participant"),
        )
        return Response(s.submission_detail_data(submission, submission_results(submission)))
