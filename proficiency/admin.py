from django.contrib import admin

from proficiency.models import Comparison, Device, Kit, KitItem, MeasurementPoint, ReferenceValue


class DeviceInline(admin.TabularInline):
    model = Device
    extra = 0


@admin.register(Comparison)
class ComparisonAdmin(admin.ModelAdmin):
    list_display = ["code", "title", "protocol", "status", "submission_deadline", "created_at"]
    list_filter = ["status", "protocol", "assigned_value_method", "sigma_pt_mode"]
    search_fields = ["code", "title", "description"]
    filter_horizontal = ["coordinators"]
    inlines = [DeviceInline]
    # open, close and publish are transitions with their checks, e-mails and audit entry
    # (the coordinator's pages and the API), never a field to edit
    readonly_fields = ["status"]


@admin.register(Device)
class DeviceAdmin(admin.ModelAdmin):
    list_display = ["name", "comparison", "model", "serial", "nominal_sensitivity", "unit"]
    list_filter = ["comparison", "model", "tolerance_distribution"]
    search_fields = ["name", "model", "serial", "comparison__code"]


@admin.register(MeasurementPoint)
class MeasurementPointAdmin(admin.ModelAdmin):
    list_display = [
        "comparison",
        "device",
        "axis",
        "frequency_hz",
        "bench",
        "direction",
        "amplitude_m_s2",
    ]
    list_filter = ["comparison", "bench", "direction", "axis", "device__name"]
    search_fields = ["comparison__code", "device__name"]
    list_select_related = ["comparison", "device"]


@admin.register(ReferenceValue)
class ReferenceValueAdmin(admin.ModelAdmin):
    list_display = ["measurement_point", "source", "value", "standard_uncertainty", "created_at"]
    list_filter = ["source", "measurement_point__comparison"]
    search_fields = ["measurement_point__device__name", "note"]
    list_select_related = ["measurement_point__device"]


@admin.register(Kit)
class KitAdmin(admin.ModelAdmin):
    list_display = ["name", "comparison"]
    list_filter = ["comparison"]
    search_fields = ["name", "comparison__code"]


@admin.register(KitItem)
class KitItemAdmin(admin.ModelAdmin):
    list_display = ["kit", "device", "serial"]
    list_filter = ["kit__comparison"]
    search_fields = ["serial", "kit__name", "device__name"]
    list_select_related = ["kit__comparison", "device"]
