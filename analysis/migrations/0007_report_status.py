"""Report.status: the status printed in the file (preliminary or final).

Existing reports: final when issued after the comparison's publication (the audit log's
record of the status change), else preliminary; a preliminary report of a published
comparison is marked superseded, and the reports task of Celery beat issues its final
version (it sends the task of every published comparison missing a final report).
"""

from django.db import migrations, models


def _published_at(apps, comparison_id):
    try:
        LogEntry = apps.get_model("auditlog", "LogEntry")
        ContentType = apps.get_model("contenttypes", "ContentType")
    except LookupError:
        return None
    kind = ContentType.objects.filter(app_label="proficiency", model="comparison").first()
    if kind is None:
        return None
    entries = LogEntry.objects.filter(content_type=kind, object_pk=str(comparison_id))
    for changes, at in entries.order_by("timestamp").values_list("changes", "timestamp"):
        status = (changes or {}).get("status") if isinstance(changes, dict) else None
        if isinstance(status, list) and status and status[-1] == "published":
            return at
    return None


def forwards(apps, schema_editor):
    Report = apps.get_model("analysis", "Report")
    published = (
        Report.objects.filter(comparison__status="published")
        .values_list("comparison_id", flat=True)
        .distinct()
    )
    for comparison_id in list(published):
        at = _published_at(apps, comparison_id)
        reports = Report.objects.filter(comparison_id=comparison_id)
        if at is not None:
            reports.filter(created_at__gte=at).update(status="final")
        reports.filter(status="preliminary", superseded=False).update(superseded=True)


class Migration(migrations.Migration):
    dependencies = [
        ("analysis", "0006_run_heartbeats_and_claims"),
        ("auditlog", "0015_alter_logentry_changes"),
        ("contenttypes", "0002_remove_content_type_name"),
        ("proficiency", "0002_report_notes"),
    ]

    operations = [
        migrations.AddField(
            model_name="report",
            name="status",
            field=models.CharField(
                choices=[("preliminary", "Preliminary"), ("final", "Final")],
                default="preliminary",
                max_length=12,
            ),
        ),
        migrations.RunPython(forwards, migrations.RunPython.noop),
    ]
