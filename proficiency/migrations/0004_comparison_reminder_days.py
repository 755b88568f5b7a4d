# Existing comparisons get no reminders (their behaviour before the field existed); a new
# comparison gets the default, 7 and 1 days before its deadline (docs/lifecycles.md §6).

from django.db import migrations, models

import proficiency.models


class Migration(migrations.Migration):
    dependencies = [
        ("proficiency", "0003_assigned_value_methods_median_niqr_q_hampel"),
    ]

    operations = [
        migrations.AddField(
            model_name="comparison",
            name="reminder_days",
            field=models.CharField(blank=True, default="", max_length=60),
            preserve_default=False,
        ),
        migrations.AlterField(
            model_name="comparison",
            name="reminder_days",
            field=models.CharField(
                blank=True,
                default="7,1",
                help_text="Days before the deadline on which laboratories that have not "
                "submitted are reminded, e.g. 7,1 (empty: no reminders).",
                max_length=60,
                validators=[proficiency.models.validate_reminder_days],
            ),
        ),
    ]
