from django.apps import AppConfig


class CoordinationConfig(AppConfig):
    """No models: the coordinator's pages, setup API and ``load_demo`` over the other apps."""

    name = "coordination"
    verbose_name = "Coordination"
