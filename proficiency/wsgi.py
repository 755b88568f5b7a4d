"""WSGI entry point (gunicorn proficiency.wsgi)."""

import os

from django.core.wsgi import get_wsgi_application

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "proficiency.settings")

application = get_wsgi_application()
