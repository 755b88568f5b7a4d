from django.apps import AppConfig


class ProficiencyConfig(AppConfig):
    name = "proficiency"
    verbose_name = "Comparisons"

    def ready(self) -> None:
        from auditlog.registry import auditlog

        from proficiency import models

        auditlog.register(models.Comparison, m2m_fields={"coordinators"})
        auditlog.register(models.Device)
