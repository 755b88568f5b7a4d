"""Celery application. Tasks are discovered from the installed apps' ``tasks`` modules."""

import os

# The recomputation of raw records (labs.tasks) does many small matrix products; BLAS
# threads only add overhead there and fight over the cores other workers use.  Set
# before numpy is first imported, i.e. before Django loads any app.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from celery import Celery

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")

app = Celery("proficiency")
app.config_from_object("django.conf:settings", namespace="CELERY")
app.autodiscover_tasks()
