from django.contrib import admin

from analysis.models import (
    AnalysisChunk,
    AnalysisRun,
    AssignedValue,
    CompatibilityMatrix,
    KitPointFit,
    KitScore,
    Publication,
    Report,
    ReportBatch,
    ReportDownload,
    RoundArchive,
    Score,
)
from common.admin_site import RecordedByServicesAdmin


@admin.register(AnalysisRun)
class AnalysisRunAdmin(RecordedByServicesAdmin):
    list_display = ["id", "comparison", "status", "progress", "stage", "created_at", "finished_at"]
    list_filter = ["status", "comparison"]
    search_fields = ["comparison__code", "error"]


@admin.register(AnalysisChunk)
class AnalysisChunkAdmin(RecordedByServicesAdmin):
    list_display = ["run", "index", "n_results", "done", "attempts", "seconds", "peak_rss_kb"]
    list_filter = ["done", "run__comparison"]
    search_fields = ["run__comparison__code"]
    raw_id_fields = ["run"]
    readonly_fields = ["moments"]


@admin.register(AssignedValue)
class AssignedValueAdmin(RecordedByServicesAdmin):
    list_display = ["measurement_point", "run", "value", "standard_uncertainty", "method"]
    list_filter = ["method", "run__comparison"]
    search_fields = ["measurement_point__device__name"]
    raw_id_fields = ["run", "measurement_point"]


@admin.register(Score)
class ScoreAdmin(RecordedByServicesAdmin):
    list_display = ["result", "run", "en", "zeta", "z", "flag", "correlation_applied"]
    list_filter = ["flag", "correlation_applied", "run__comparison"]
    search_fields = ["result__submission__participant__code"]
    raw_id_fields = ["run", "result"]


@admin.register(Report)
class ReportAdmin(RecordedByServicesAdmin):
    list_display = [
        "comparison",
        "kind",
        "participant",
        "version",
        "status",
        "superseded",
        "created_at",
    ]
    list_filter = ["kind", "status", "superseded", "comparison"]
    search_fields = ["comparison__code", "participant__code", "sha256"]


@admin.register(ReportBatch)
class ReportBatchAdmin(RecordedByServicesAdmin):
    list_display = ["id", "comparison", "run", "report_status", "kind", "index", "status",
                    "attempts", "heartbeat_at", "finished_at"]  # fmt: skip
    list_filter = ["status", "kind", "report_status", "comparison"]
    search_fields = ["comparison__code", "error"]
    raw_id_fields = ["run"]


@admin.register(Publication)
class PublicationAdmin(RecordedByServicesAdmin):
    list_display = ["id", "comparison", "run", "status", "progress", "stage", "attempts",
                    "created_at", "finished_at"]  # fmt: skip
    list_filter = ["status", "comparison"]
    search_fields = ["comparison__code", "error"]
    raw_id_fields = ["run", "requested_by"]


@admin.register(CompatibilityMatrix)
class CompatibilityMatrixAdmin(RecordedByServicesAdmin):
    list_display = ["factor", "group_key", "run", "incompatible_pairs"]
    list_filter = ["factor", "run__comparison"]
    search_fields = ["group_key"]


@admin.register(ReportDownload)
class ReportDownloadAdmin(RecordedByServicesAdmin):
    list_display = ["report", "user", "laboratory", "at"]
    list_filter = ["report__comparison", "report__kind"]
    search_fields = ["report__comparison__code", "user__username", "laboratory__name"]
    raw_id_fields = ["report"]


@admin.register(RoundArchive)
class RoundArchiveAdmin(RecordedByServicesAdmin):
    list_display = ["id", "comparison", "run", "participant", "status", "size", "attempts",
                    "finished_at"]  # fmt: skip
    list_filter = ["status", "comparison"]
    search_fields = ["comparison__code", "participant__code", "error"]
    raw_id_fields = ["run", "participant"]


@admin.register(KitPointFit)
class KitPointFitAdmin(RecordedByServicesAdmin):
    """A run's drift and link per point (docs/domain.md §13, §14): shown, not edited."""

    list_display = ["measurement_point", "run", "reference", "chi2", "dof"]
    list_filter = ["reference", "run__comparison"]
    search_fields = ["measurement_point__device__name", "run__comparison__code"]
    raw_id_fields = ["run", "measurement_point"]


@admin.register(KitScore)
class KitScoreAdmin(RecordedByServicesAdmin):
    """A result's kit, drift correction and linked degree of equivalence."""

    list_display = ["result", "run", "kit", "measured_on", "drift_correction", "linked_d", "u_link"]
    list_filter = ["kit", "run__comparison"]
    search_fields = ["result__submission__participant__code", "kit__name"]
    raw_id_fields = ["run", "result"]
