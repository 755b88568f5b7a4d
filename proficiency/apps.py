from django.apps import AppConfig


class ProficiencyConfig(AppConfig):
    name = "proficiency"
    verbose_name = "Comparisons"
