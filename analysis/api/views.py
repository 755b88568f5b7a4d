"""Coordinator API (docs/interfaces.md §3): analysis runs, scores, compatibility, publication,
life-cycle transitions and submission review.

Participants see scores and matrices only after publication, their own scores only,
other laboratories by code. Everything outside the caller's scope answers 404.
"""

from __future__ import annotations

from typing import Any, cast

from django.contrib.auth.models import User
from django.db.models import QuerySet
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import generics, serializers, status
from rest_framework.request import Request
from rest_framework.response import Response

from analysis.api import serializers as s
from analysis.core.groups import CoreInputError
from analysis.kit_results import with_kit_scores
from analysis.models import AnalysisRun, KitPointFit, Publication, Score
from analysis.pipeline import matrix_record
from analysis.publication import publication_start
from analysis.selectors import SCORE_FILTERS, current_run, lab_matrices, run_matrices, run_scores
from analysis.services import analysis_run_cancel, analysis_run_start
from common.errors import NotVisible, StateConflict, ValidationFailed
from common.pagination import PageNumberPagination
from labs.access import (
    ComparisonAccess,
    caller_of,
    comparisons_for,
    published_or_coordinator,
    require_coordinator,
)
from labs.api.views import ApiView
from labs.models import Result, Submission
from labs.review import submission_decide, submission_request_check
from labs.services import comparison_move
from proficiency.selectors import POINT_ORDER

FACTORS = ("axis", "frequency", "device", "bench", "direction", "lab")
#: a point's keys as query parameters and their lookups from a ``KitPointFit``
POINT_KEYS = {
    k: f"measurement_point__{'device__name' if k == 'device' else k}"
    for k in ("device", "axis", "frequency_hz", "bench", "direction", "quantity")
}
POINT_FILTERS = [
    OpenApiParameter(k, str, description=f"only this {k}") for k in SCORE_FILTERS
]  # fmt: skip


def number(value: str, field: str) -> float:
    """A numeric query parameter, or a 400 that names it (never a 500 from the ORM)."""
    try:
        return float(value)
    except ValueError:
        raise ValidationFailed(
            f"{field} must be a number, got {value!r}.",
            errors=[{"row": None, "field": field, "message": "must be a number"}],
        ) from None


def shown_run(access: ComparisonAccess) -> AnalysisRun:
    run = current_run(access.comparison)
    if run is None:
        raise StateConflict(f"{access.comparison.code} has no successful analysis run yet.")
    return run


class AnalysisRunCollection(ApiView, generics.ListAPIView):
    """GET: the comparison's runs, newest first. POST: start a run (202)."""

    serializer_class = s.AnalysisRunSerializer

    def get_queryset(self) -> QuerySet[AnalysisRun]:
        if getattr(self, "swagger_fake_view", False):  # schema generation: no request
            return AnalysisRun.objects.none()
        access = self.access(self.kwargs["code"])
        require_coordinator(access)
        return access.comparison.analysis_runs.order_by("-created_at", "-pk")

    @extend_schema(request=None, responses={202: s.AnalysisRunSerializer})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        # require_coordinator passed: a person (keys never coordinate)
        run = analysis_run_start(comparison=access.comparison, user=cast(User, request.user))
        run.refresh_from_db()
        return Response(s.AnalysisRunSerializer(run).data, status=status.HTTP_202_ACCEPTED)


class AnalysisRunDetail(ApiView):
    """Status, progress 0–100, stage and error of one run (coordinators)."""

    @extend_schema(responses=s.AnalysisRunSerializer)
    def get(self, request: Request, pk: int) -> Response:
        return Response(s.AnalysisRunSerializer(coordinated_run(self, request, pk)).data)


def coordinated_run(view: ApiView, request: Request, pk: int) -> AnalysisRun:
    """Run ``pk`` if the caller coordinates its comparison; 404 otherwise."""
    run = AnalysisRun.objects.filter(
        pk=pk, comparison__in=comparisons_for(caller_of(request))
    ).first()
    if run is None or not view.access(run.comparison.code).is_coordinator:
        raise NotVisible(f"No analysis run {pk} is visible to you.")
    return run


class AnalysisRunCancel(ApiView):
    """Cancel a pending or running run (coordinators): it keeps no outputs, and a new run
    can be started at once.  409 if the run has ended already."""

    @extend_schema(request=None, responses={200: s.AnalysisRunSerializer})
    def post(self, request: Request, pk: int) -> Response:
        run = coordinated_run(self, request, pk)  # a coordinator's: a person
        run = analysis_run_cancel(run=run, user=cast(User, request.user))
        return Response(s.AnalysisRunSerializer(run).data)


class ScoreList(ApiView, generics.ListAPIView):
    """Scores of the current run: coordinators all; participants their own after publication."""

    serializer_class = s.ScoreSerializer

    @extend_schema(parameters=POINT_FILTERS)
    def get(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        return super().get(request, *args, **kwargs)

    def get_queryset(self) -> QuerySet[Score]:
        if getattr(self, "swagger_fake_view", False):
            return Score.objects.none()
        access = self.access(self.kwargs["code"])
        published_or_coordinator(access)
        filters = {k: self.request.query_params.get(k, "") for k in SCORE_FILTERS}
        if filters["frequency_hz"]:
            number(filters["frequency_hz"], "frequency_hz")
        if not access.is_coordinator:
            assert access.participant is not None
            filters["lab"] = access.participant.code
        return with_kit_scores(run_scores(shown_run(access), filters))


class CovariancePages(PageNumberPagination):
    """One point per page by default (a point of 300 participants is two 300 × 300
    matrices); ``page_size`` up to 100, and no more points than keep a page within
    :attr:`max_entries` matrix entries for the round's number of participants (the view's
    ``n_bound``): 300 participants, two points a page."""

    page_size = 1
    page_size_query_param = "page_size"
    max_page_size = 100
    max_entries = 400_000  # covariance and correlation entries a page may hold (≈ 8 MB)

    def paginate_queryset(self, queryset: Any, request: Request, view: Any = None) -> Any:
        n = max(getattr(view, "n_bound", 0), 1)
        self.max_page_size = max(1, min(type(self).max_page_size, self.max_entries // (2 * n * n)))
        return super().paginate_queryset(queryset, request, view)


class DoeCovarianceList(ApiView, generics.ListAPIView):
    """The covariance and correlation of the linked degrees of equivalence per point of the
    current run of a round with kits (docs/domain.md §14): coordinators only (a participant
    gets 403: every entry is a pair of laboratories)."""

    serializer_class = s.DoeCovarianceSerializer
    pagination_class = CovariancePages

    @extend_schema(parameters=POINT_FILTERS[:6])
    def get(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        return super().get(request, *args, **kwargs)

    def get_queryset(self) -> QuerySet[KitPointFit]:
        if getattr(self, "swagger_fake_view", False):
            return KitPointFit.objects.none()
        access = self.access(self.kwargs["code"])
        require_coordinator(access)
        self.n_bound = access.comparison.participants.count()  # the matrices' size bound
        filters = {k: self.request.query_params.get(k, "") for k in POINT_KEYS}
        if filters["frequency_hz"]:
            number(filters["frequency_hz"], "frequency_hz")
        lookups = {POINT_KEYS[k]: v for k, v in filters.items() if v}
        return (KitPointFit.objects.filter(run=shown_run(access), **lookups)
                .exclude(reference="").select_related("measurement_point__device")
                .order_by(*POINT_ORDER))  # fmt: skip


class CompatibilityQuery(serializers.Serializer):
    factor = serializers.ChoiceField(choices=FACTORS)
    device = serializers.CharField(required=False)
    axis = serializers.CharField(required=False)
    frequency_hz = serializers.CharField(required=False)
    bench = serializers.CharField(required=False)
    direction = serializers.CharField(required=False)

    def validate_frequency_hz(self, value: str) -> str:
        number(value, "frequency_hz")
        return value


class CompatibilityView(ApiView):
    """Compatibility matrices of one factor; ``lab`` is computed for the selected points."""

    @extend_schema(parameters=[CompatibilityQuery], responses=s.MatrixSerializer(many=True))
    def get(self, request: Request, code: str) -> Response:
        access = self.access(code)
        published_or_coordinator(access)
        query = CompatibilityQuery(data=request.query_params)
        if not query.is_valid():
            raise ValidationFailed(
                "Bad query: give factor=axis|frequency|device|bench|direction|lab.",
                errors=[{"row": None, "field": k, "message": str(v[0])}
                        for k, v in query.errors.items()],
            )  # fmt: skip
        params = dict(query.validated_data)
        factor = params.pop("factor")
        if factor == "lab":
            try:
                found = lab_matrices(shown_run(access), params)
            except CoreInputError as exc:  # e.g. no accepted result at the selected points
                raise ValidationFailed(
                    "No lab matrix for this selection.",
                    errors=[{"row": None, "field": None, "message": str(exc)}],
                ) from None
            data = [matrix_record(m) for m in found]
        else:
            data = [m.record() for m in run_matrices(shown_run(access), factor, params)]
        return Response(data)


class TransitionSerializer(serializers.Serializer):
    to = serializers.ChoiceField(choices=["open", "closed"])


class ComparisonTransition(ApiView):
    """Open or close the comparison (coordinators); publication has its own endpoint."""

    @extend_schema(request=TransitionSerializer, responses={200: s.ComparisonStateSerializer})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        body = TransitionSerializer(data=request.data)
        if not body.is_valid():
            raise ValidationFailed("Give to=open or to=closed.")
        c = comparison_move(comparison=access.comparison, to=body.validated_data["to"])
        return Response(s.ComparisonStateSerializer(c).data)


class Publish(ApiView):
    """Ask for publication (coordinators): 202 with the comparison (still analysed until
    the job publishes it) and the ``publication`` job, whose ``url`` shows its progress.
    409 at once when it cannot be published, or while a publication is under way."""

    @extend_schema(request=None, responses={202: s.PublishAnswerSerializer})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        # require_coordinator passed: a person (keys never coordinate)
        job = publication_start(comparison=access.comparison, user=cast(User, request.user))
        job = Publication.objects.select_related("comparison").get(pk=job.pk)  # eager: ended
        answer = s.ComparisonStateSerializer(job.comparison).data | {
            "publication": s.PublicationSerializer(job, context={"request": request}).data
        }
        return Response(answer, status=status.HTTP_202_ACCEPTED)


class PublicationDetail(ApiView):
    """Status, progress 0–100, stage and error of one publication (coordinators)."""

    @extend_schema(responses=s.PublicationSerializer)
    def get(self, request: Request, pk: int) -> Response:
        job = Publication.objects.filter(
            pk=pk, comparison__in=comparisons_for(caller_of(request))
        ).select_related("comparison").first()  # fmt: skip
        if job is None or not self.access(job.comparison.code).is_coordinator:
            raise NotVisible(f"No publication {pk} is visible to you.")
        return Response(s.PublicationSerializer(job, context={"request": request}).data)


class DecisionSerializer(serializers.Serializer):
    decision = serializers.ChoiceField(choices=["accept", "reject"])
    message = serializers.CharField(required=False, allow_blank=True, default="")


def _submission(access: ComparisonAccess, participant: str, version: int) -> Submission:
    found = Submission.objects.filter(
        participant__comparison=access.comparison, participant__code=participant, version=version
    ).first()
    if found is None:
        raise NotVisible(f"No submission version {version} of that participant is visible to you.")
    return found


class SubmissionDecision(ApiView):
    """Accept or reject a submitted version (coordinators); audited, the lab is told."""

    @extend_schema(request=DecisionSerializer, responses={200: s.DecisionResultSerializer})
    def post(self, request: Request, code: str, participant: str, version: int) -> Response:
        access = self.access(code)
        require_coordinator(access)
        body = DecisionSerializer(data=request.data)
        if not body.is_valid():
            raise ValidationFailed("Give decision=accept or decision=reject (and a message).")
        decided = submission_decide(
            submission=_submission(access, participant, version),
            decision=body.validated_data["decision"],
            message=body.validated_data["message"],
            user=cast(User, request.user),  # a coordinator: a person, not a key
        )
        return Response(s.DecisionResultSerializer(decided).data)


class CheckRequestSerializer(serializers.Serializer):
    result = serializers.IntegerField(help_text="id of the result to check")


class RequestCheck(ApiView):
    """Ask a lab to check one result without revealing the deviation (CIPM practice)."""

    @extend_schema(request=CheckRequestSerializer, responses={202: None})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        body = CheckRequestSerializer(data=request.data)
        if not body.is_valid():
            raise ValidationFailed("Give result=<result id>.")
        result = (
            Result.objects.select_related("measurement_point__device", "submission__participant")
            .filter(
                pk=body.validated_data["result"],
                submission__participant__comparison=access.comparison,
            )
            .first()
        )
        if result is None:
            raise NotVisible("No such result in this comparison.")
        submission_request_check(result=result, user=cast(User, request.user))  # a coordinator
        return Response(status=status.HTTP_202_ACCEPTED)
