"""The migration adding ``reminder_days`` keeps every comparison and gives the existing ones
their old behaviour, no reminders; a comparison made afterwards reminds 7 and 1 days out."""

import pytest
from django.db import connection
from django.db.migrations.executor import MigrationExecutor

BEFORE = [("proficiency", "0003_assigned_value_methods_median_niqr_q_hampel"),
          ("labs", "0006_result_repeatability")]  # fmt: skip
AFTER = [("proficiency", "0004_comparison_reminder_days"), ("labs", "0008_notice")]


@pytest.mark.django_db(transaction=True)
def test_existing_comparisons_get_no_reminders():
    executor = MigrationExecutor(connection)
    executor.migrate(BEFORE)
    old = executor.loader.project_state(BEFORE).apps.get_model("proficiency", "Comparison")
    old.objects.create(code="IMU-OLD", title="Before the field")
    executor = MigrationExecutor(connection)
    executor.loader.build_graph()
    executor.migrate(AFTER)
    new = executor.loader.project_state(AFTER).apps.get_model("proficiency", "Comparison")
    assert list(new.objects.values_list("code", "reminder_days")) == [("IMU-OLD", "")]
    assert new.objects.create(code="IMU-NEW", title="After").reminder_days == "7,1"
    executor = MigrationExecutor(connection)
    executor.loader.build_graph()
    executor.migrate(executor.loader.graph.leaf_nodes())  # every app's latest, for the next tests
