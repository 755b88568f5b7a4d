from django.apps import AppConfig


class LabsConfig(AppConfig):
    name = "labs"
    verbose_name = "Laboratories"

    def ready(self) -> None:
        # in ready(): the models (and auditlog's) need the app registry
        from auditlog.registry import auditlog

        from labs import models

        auditlog.register(models.Laboratory)
        auditlog.register(models.Membership)
        auditlog.register(models.Participant)
        auditlog.register(models.Submission)
        auditlog.register(models.LabAPIKey, exclude_fields=["hashed_key"])
