"""Report API under ``/api/v1/``: list a comparison's reports, issue one, download a PDF.

Downloads go through the report's random ``token`` (never its id), are checked against
the caller's scope on every request and logged as :class:`ReportDownload` rows.
"""

from __future__ import annotations

from django.http import FileResponse
from django.urls import path
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema
from rest_framework import serializers, status
from rest_framework.request import Request
from rest_framework.response import Response

from analysis.access import download_name, report_for_download, reports_visible
from analysis.models import Report, ReportDownload
from analysis.reports.assemble import report_status
from analysis.reports.services import report_issue, report_notes_update
from common.errors import NotVisible
from labs.access import caller_of, require_coordinator
from labs.api.views import ApiView, validated
from proficiency.models import Comparison


class ReportSerializer(serializers.ModelSerializer):
    participant = serializers.CharField(source="participant.code", allow_null=True, default=None)
    download_url = serializers.SerializerMethodField()

    class Meta:
        model = Report
        fields = [
            "id",
            "kind",
            "participant",
            "version",
            "status",
            "superseded",
            "run",
            "sha256",
            "size",
            "software_version",
            "created_at",
            "download_url",
        ]

    def get_download_url(self, report: Report) -> str:
        return f"/api/v1/reports/{report.token}/pdf"


class IssueSerializer(serializers.Serializer):
    kind = serializers.ChoiceField(choices=Report.Kind.choices)
    participant = serializers.CharField(required=False, allow_blank=True, default="")
    comments = serializers.CharField(required=False, allow_blank=True, default="")


class ReportCollection(ApiView):
    """GET: the reports you may read. POST (coordinators): issue a new version now."""

    @extend_schema(responses=ReportSerializer(many=True))
    def get(self, request: Request, code: str) -> Response:
        found = reports_visible(self.access(code))
        return Response(ReportSerializer(found, many=True).data)

    @extend_schema(request=IssueSerializer, responses={201: ReportSerializer})
    def post(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        data = validated(IssueSerializer, request.data)
        participant = None
        if data["participant"]:
            participant = access.comparison.participants.filter(code=data["participant"]).first()
            if participant is None:
                raise NotVisible(f"No participant {data['participant']!r} in {code}.")
        report = report_issue(
            comparison=access.comparison,
            kind=data["kind"],
            participant=participant,
            comments=data["comments"],
        )
        return Response(ReportSerializer(report).data, status=status.HTTP_201_CREATED)


class ReportNotesSerializer(serializers.Serializer):
    comments = serializers.CharField(
        source="report_comments",
        required=False,
        allow_blank=True,
        default="",
        trim_whitespace=False,
        help_text="Comments on performance and advice on interpretation (plain text).",
    )
    conclusions = serializers.CharField(
        source="report_conclusions",
        required=False,
        allow_blank=True,
        default="",
        trim_whitespace=False,
    )
    authorised_by_name = serializers.CharField(required=False, allow_blank=True, default="")
    authorised_by_role = serializers.CharField(required=False, allow_blank=True, default="")
    status = serializers.SerializerMethodField(help_text="Status the next reports will carry.")

    def get_status(self, comparison: Comparison) -> str:
        return report_status(comparison)


class ReportNotes(ApiView):
    """The coordinator's comments, conclusions and the reports' authoriser (coordinators).

    PUT replaces all four; the next issued reports print them. Audit-logged."""

    @extend_schema(responses=ReportNotesSerializer)
    def get(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        return Response(ReportNotesSerializer(access.comparison).data)

    @extend_schema(request=ReportNotesSerializer, responses=ReportNotesSerializer)
    def put(self, request: Request, code: str) -> Response:
        access = self.access(code)
        require_coordinator(access)
        data = validated(ReportNotesSerializer, request.data)
        comparison = report_notes_update(
            comparison=access.comparison,
            comments=data["report_comments"],
            conclusions=data["report_conclusions"],
            authorised_by_name=data["authorised_by_name"],
            authorised_by_role=data["authorised_by_role"],
            user=request.user,
        )
        return Response(ReportNotesSerializer(comparison).data)


class ReportPdf(ApiView):
    """The PDF of one report, by its download token; every download is logged."""

    @extend_schema(responses={(200, "application/pdf"): OpenApiTypes.BINARY})
    def get(self, request: Request, token: str) -> FileResponse:
        caller = caller_of(request)
        report = report_for_download(caller, token)
        ReportDownload.objects.create(
            report=report,
            user_id=caller.user.pk if caller.user else None,
            laboratory=caller.laboratory,
        )
        return FileResponse(
            report.file.open("rb"),
            as_attachment=True,
            filename=download_name(report),
            content_type="application/pdf",
        )


urlpatterns = [
    path("comparisons/<slug:code>/reports/", ReportCollection.as_view(), name="report-list"),
    path("reports/<str:token>/pdf", ReportPdf.as_view(), name="report-pdf"),
    path("comparisons/<slug:code>/report-notes/", ReportNotes.as_view(), name="report-notes"),
]
