"""Django project: settings from the environment, the root URLconf, the Celery app, WSGI/ASGI.

Only entry points import this package (manage.py, gunicorn, celery -A config, the tests'
conftest); no app does (docs/architecture.md §5).
"""

from config.celery import app as celery_app

__all__ = ["celery_app"]
