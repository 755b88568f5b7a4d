"""Proficiency-testing service: Django project and the comparison domain."""

from proficiency.celery import app as celery_app

__all__ = ["celery_app"]
__version__ = "0.1.0"
