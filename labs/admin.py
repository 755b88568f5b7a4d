from django.contrib import admin
from rest_framework_api_key.admin import APIKeyModelAdmin

from common.admin_site import RecordedByServicesAdmin, ViewOnly
from labs.models import (
    Enrolment,
    Handover,
    KitMeasurement,
    KitSlot,
    LabAPIKey,
    Laboratory,
    Membership,
    Notice,
    Participant,
    RawFile,
    RawRecomputation,
    RawRecord,
    Result,
    Submission,
    SubmissionKey,
)


@admin.register(Laboratory)
class LaboratoryAdmin(admin.ModelAdmin):
    list_display = ["name", "country", "accreditation_body", "accreditation_number"]
    list_filter = ["country", "accreditation_body"]
    search_fields = ["name", "accreditation_number", "contact_name", "contact_email"]


@admin.register(Membership)
class MembershipAdmin(admin.ModelAdmin):
    list_display = ["user", "laboratory", "role"]
    list_filter = ["role", "laboratory"]
    search_fields = ["user__username", "user__email", "laboratory__name"]
    list_select_related = ["user", "laboratory"]


@admin.register(Participant)
class ParticipantAdmin(RecordedByServicesAdmin):
    list_display = ["code", "comparison", "laboratory", "is_reference", "invited_at"]
    list_filter = ["comparison", "is_reference"]
    search_fields = ["code", "laboratory__name", "comparison__code"]
    list_select_related = ["comparison", "laboratory"]


class ResultInline(ViewOnly, admin.TabularInline):
    model = Result
    extra = 0
    can_delete = False
    raw_id_fields = ["measurement_point"]


@admin.register(Submission)
class SubmissionAdmin(RecordedByServicesAdmin):
    list_display = ["participant", "version", "status", "source", "submitted_at", "submitted_by"]
    list_filter = ["status", "source", "participant__comparison"]
    search_fields = ["participant__code", "participant__laboratory__name"]
    list_select_related = ["participant__comparison", "submitted_by"]
    inlines = [ResultInline]


@admin.register(Notice)
class NoticeAdmin(RecordedByServicesAdmin):
    list_display = ["created_at", "kind", "comparison", "laboratory", "participant",
                    "emailed_at", "read_at"]  # fmt: skip
    list_filter = ["kind", "comparison"]
    search_fields = ["subject", "dedupe_key", "laboratory__name", "participant__code"]
    list_select_related = ["comparison", "laboratory", "participant"]
    raw_id_fields = ["laboratory", "comparison", "participant"]


@admin.register(Enrolment)
class EnrolmentAdmin(RecordedByServicesAdmin):
    """Applications are decided on the coordinator pages (labs.enrolment); shown here only."""

    list_display = ["created_at", "comparison", "laboratory", "status", "participant",
                    "decided_at"]  # fmt: skip
    list_filter = ["status", "comparison"]
    search_fields = ["laboratory__name", "comparison__code", "note", "reason"]
    list_select_related = ["comparison", "laboratory", "participant"]
    raw_id_fields = ["laboratory", "comparison", "participant", "applied_by", "decided_by"]


@admin.register(SubmissionKey)
class SubmissionKeyAdmin(RecordedByServicesAdmin):
    list_display = ["participant", "key", "submission", "created_at"]
    list_filter = ["participant__comparison"]
    search_fields = ["key", "participant__code", "participant__laboratory__name"]
    list_select_related = ["participant__comparison", "submission"]
    raw_id_fields = ["participant", "submission"]


@admin.register(Result)
class ResultAdmin(RecordedByServicesAdmin):
    list_display = [
        "submission",
        "measurement_point",
        "value",
        "unit",
        "expanded_uncertainty",
        "coverage_factor",
        "standard_uncertainty",
    ]
    list_filter = [
        "submission__participant__comparison",
        "submission__status",
        "measurement_point__bench",
        "measurement_point__axis",
        "measurement_point__device__name",
    ]
    search_fields = ["submission__participant__code", "submission__participant__laboratory__name"]
    list_select_related = ["submission__participant", "measurement_point__device"]
    raw_id_fields = ["submission", "measurement_point"]


@admin.register(LabAPIKey)
class LabAPIKeyAdmin(APIKeyModelAdmin):
    # the library's attributes are typed as tuples of their exact length: longer ones here
    list_display = [*APIKeyModelAdmin.list_display, "laboratory"]  # type: ignore[assignment]
    list_filter = [*APIKeyModelAdmin.list_filter, "laboratory"]  # type: ignore[assignment]
    search_fields = [*APIKeyModelAdmin.search_fields, "laboratory__name"]  # type: ignore[assignment]


class CreatedByUploadOnly(RecordedByServicesAdmin):
    """Raw data is created by the upload service only (it validates and hashes the
    files) and never modified: the admin views and deletes."""


@admin.register(RawFile)
class RawFileAdmin(CreatedByUploadOnly):
    list_display = ["sha256", "size", "created_at"]
    list_filter = ["created_at"]
    search_fields = ["sha256"]


class RawRecomputationInline(admin.StackedInline):
    model = RawRecomputation
    extra = 0
    can_delete = False
    readonly_fields = ("status", "error", "sensitivity", "expanded_uncertainty", "en", "fs_hz")
    fields = readonly_fields


@admin.register(RawRecord)
class RawRecordAdmin(CreatedByUploadOnly):
    list_display = ["data_name", "participant", "measurement_point", "created_at"]
    list_filter = [
        "participant__comparison",
        "measurement_point__bench",
        "recomputation__status",
    ]
    search_fields = ["data_name", "participant__code", "data_file__sha256"]
    list_select_related = ["participant__comparison", "measurement_point__device"]
    raw_id_fields = ["participant", "submission", "measurement_point", "data_file",
                     "reference_file", "uploaded_by"]  # fmt: skip
    inlines = [RawRecomputationInline]


@admin.register(RawRecomputation)
class RawRecomputationAdmin(CreatedByUploadOnly):
    list_display = ["record", "status", "sensitivity", "reported_value", "en", "fs_hz"]
    list_filter = ["status", "method", "software_version", "record__participant__comparison"]
    search_fields = ["record__participant__code", "record__data_name"]
    list_select_related = ["record__participant"]
    raw_id_fields = ["record"]


@admin.register(KitSlot)
class KitSlotAdmin(RecordedByServicesAdmin):
    list_display = ["kit", "position", "participant", "starts_on", "ends_on"]
    list_filter = ["kit__comparison", "kit"]
    search_fields = ["kit__name", "participant__code", "kit__comparison__code"]
    list_select_related = ["kit__comparison", "participant"]


@admin.register(Handover)
class HandoverAdmin(RecordedByServicesAdmin):
    list_display = ["kit", "from_slot", "to_slot", "dispatched_at", "received_at", "condition"]
    list_filter = ["condition", "kit__comparison"]
    search_fields = ["kit__name", "kit__comparison__code", "carrier_note", "condition_note"]
    list_select_related = ["kit__comparison", "from_slot", "to_slot"]


@admin.register(KitMeasurement)
class KitMeasurementAdmin(RecordedByServicesAdmin):
    list_display = ["kit", "measurement_point", "participant", "measured_on", "value",
                    "expanded_uncertainty"]  # fmt: skip
    list_filter = ["kit__comparison", "kit"]
    search_fields = ["kit__name", "kit__comparison__code", "measurement_point__device__name"]
    list_select_related = ["kit__comparison", "measurement_point__device", "participant"]
