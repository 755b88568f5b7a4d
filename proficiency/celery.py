"""Celery application. Tasks are discovered from the installed apps' ``tasks`` modules."""

import os

from celery import Celery

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "proficiency.settings")

app = Celery("proficiency")
app.config_from_object("django.conf:settings", namespace="CELERY")
app.autodiscover_tasks()
