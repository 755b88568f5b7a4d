from django.apps import AppConfig


class ProficiencyConfig(AppConfig):
    name = "proficiency"
    verbose_name = "Comparisons"

    def ready(self) -> None:
        # in ready(): the models (and auditlog's) need the app registry
        from auditlog.registry import auditlog

        from proficiency import models

        auditlog.register(models.Comparison, m2m_fields={"coordinators"})
        auditlog.register(models.Device)
