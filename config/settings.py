"""Settings, read from the environment (django-environ).

With no environment variable set the service runs embedded, for development:
SQLite in the project folder, Celery tasks executed eagerly in-process, DEBUG on.
Production sets at least SECRET_KEY, DEBUG=false, ALLOWED_HOSTS, DATABASE_URL
and CELERY_BROKER_URL (see README, "Configuration").
"""

import base64
import hashlib
from datetime import timedelta
from pathlib import Path

import environ
from celery.schedules import crontab
from django.core.exceptions import ImproperlyConfigured

BASE_DIR = Path(__file__).resolve().parent.parent

env = environ.Env()
env_file = env.str("ENV_FILE", default="")
if env_file:
    environ.Env.read_env(env_file)

DEV_SECRET_KEY = "django-insecure-development-only-key-never-use-in-production"

DEBUG = env.bool("DEBUG", default=True)
SECRET_KEY = env.str("SECRET_KEY", default=DEV_SECRET_KEY)
if not DEBUG and SECRET_KEY == DEV_SECRET_KEY:
    raise ImproperlyConfigured("SECRET_KEY must be set when DEBUG is off.")
ALLOWED_HOSTS = env.list("ALLOWED_HOSTS", default=["127.0.0.1", "localhost", "[::1]", "testserver"])
CSRF_TRUSTED_ORIGINS = env.list("CSRF_TRUSTED_ORIGINS", default=[])

# Cache: DRF throttle counters and django-axes live here. In production set CACHE_URL to a
# shared cache (redis://127.0.0.1:6379/2): with the per-process default every gunicorn worker
# would count a key's requests separately, allowing several times the rate limit.
CACHES = {"default": env.cache_url("CACHE_URL", default="locmemcache://")}
if CACHES["default"]["BACKEND"] == "django.core.cache.backends.redis.RedisCache":
    # the same backend, reusing its redis.Redis client (common/cache.py)
    CACHES["default"]["BACKEND"] = "common.cache.RedisCache"

# E-mail (publication notices, password resets): printed on the console unless EMAIL_URL
# names a server, e.g. smtp+tls://user:password@mail.example.org:587, so the quick start
# needs none. With DEBUG off a server is required: the console would write valid password
# reset links into the service's log. (dummymail:// sends nothing at all, for benchmarks.)
_EMAIL = env.email_url("EMAIL_URL", default="consolemail://")
vars().update(_EMAIL)
if not DEBUG and _EMAIL["EMAIL_BACKEND"] not in (
    "django.core.mail.backends.smtp.EmailBackend",
    "django.core.mail.backends.dummy.EmailBackend",
):
    raise ImproperlyConfigured(
        "EMAIL_URL must name a mail server when DEBUG is off, e.g. "
        "smtp+tls://user:password@mail.example.org:587 (the console e-mail backend would "
        "write password reset links into the log)."
    )
DEFAULT_FROM_EMAIL = env.str("DEFAULT_FROM_EMAIL", default="proficiency-testing@localhost")
# The address of the site as laboratories reach it: e-mailed notices link to
# SITE_URL + the page's path (docs/lifecycles.md §6). The default suits the quick start.
SITE_URL = env.str("SITE_URL", default="http://127.0.0.1:8000").rstrip("/")

INSTALLED_APPS = [
    # the admin, for superusers only (common/admin_site.py)
    "common.admin_site.SuperuserAdminConfig",
    "django.contrib.auth",
    "django.contrib.contenttypes",
    "django.contrib.sessions",
    "django.contrib.messages",
    "django.contrib.staticfiles",
    "django_celery_results",
    "django_filters",
    "django_htmx",
    "auditlog",
    "axes",
    "rest_framework",
    "rest_framework_api_key",
    "drf_spectacular",
    "drf_spectacular_sidecar",
    "proficiency",
    "labs",
    "analysis",
    "coordination",
]

MIDDLEWARE = [
    "django.middleware.security.SecurityMiddleware",
    "common.middleware.ContentSecurityPolicyMiddleware",
    "common.middleware.RequestSizeLimitMiddleware",
    "common.middleware.ControlCharacterMiddleware",
    "whitenoise.middleware.WhiteNoiseMiddleware",
    "django.contrib.sessions.middleware.SessionMiddleware",
    "django.middleware.common.CommonMiddleware",
    "django.middleware.csrf.CsrfViewMiddleware",
    "django.contrib.auth.middleware.AuthenticationMiddleware",
    "django.contrib.messages.middleware.MessageMiddleware",
    "django.middleware.clickjacking.XFrameOptionsMiddleware",
    "django_htmx.middleware.HtmxMiddleware",
    "auditlog.middleware.AuditlogMiddleware",
    # Last, as django-axes asks: turns a locked-out login into the lockout answer.
    "axes.middleware.AxesMiddleware",
]

# django-axes first: it refuses a locked-out username before the password is checked.
# Logins must pass the request (the login views do; tests use force_login).
AUTHENTICATION_BACKENDS = [
    "axes.backends.AxesStandaloneBackend",
    "django.contrib.auth.backends.ModelBackend",
]

ROOT_URLCONF = "config.urls"

TEMPLATES = [
    {
        "BACKEND": "django.template.backends.django.DjangoTemplates",
        # A provider's own copies (e.g. notices/invitation.txt, notices/email.html) in
        # PROVIDER_TEMPLATES_DIR are found before the shipped ones (docs/lifecycles.md §6).
        "DIRS": [
            *([Path(p)] if (p := env.str("PROVIDER_TEMPLATES_DIR", default="")) else []),
            BASE_DIR / "templates",
        ],
        "APP_DIRS": True,
        "OPTIONS": {
            "context_processors": [
                "django.template.context_processors.request",
                "django.contrib.auth.context_processors.auth",
                "django.contrib.messages.context_processors.messages",
            ],
        },
    },
]

WSGI_APPLICATION = "config.wsgi.application"

# Embedded default: SQLite beside manage.py. DATABASE_URL=postgres://... for PostgreSQL
# (psycopg 3).
DATABASES = {
    "default": env.db("DATABASE_URL", default=f"sqlite:///{BASE_DIR / 'db.sqlite3'}"),
}
DATABASES["default"]["ATOMIC_REQUESTS"] = False
DATABASES["default"].setdefault("CONN_MAX_AGE", env.int("CONN_MAX_AGE", default=0))
if DATABASES["default"]["ENGINE"] == "django.db.backends.sqlite3":
    DATABASES["default"].setdefault("OPTIONS", {})["timeout"] = 20
DEFAULT_AUTO_FIELD = "django.db.models.BigAutoField"

AUTH_PASSWORD_VALIDATORS = [
    {"NAME": "django.contrib.auth.password_validation.UserAttributeSimilarityValidator"},
    {
        "NAME": "django.contrib.auth.password_validation.MinimumLengthValidator",
        "OPTIONS": {"min_length": 10},
    },
    {"NAME": "django.contrib.auth.password_validation.CommonPasswordValidator"},
    {"NAME": "django.contrib.auth.password_validation.NumericPasswordValidator"},
]

LANGUAGE_CODE = "en-gb"
TIME_ZONE = env.str("TIME_ZONE", default="UTC")
USE_I18N = True
USE_TZ = True

STATIC_URL = "static/"
STATIC_ROOT = Path(env.str("STATIC_ROOT", default=str(BASE_DIR / "staticfiles")))
STATICFILES_DIRS = [BASE_DIR / "static"] if (BASE_DIR / "static").is_dir() else []
# Uploaded files live outside the web root and are served only through permission-checked views.
MEDIA_ROOT = Path(env.str("MEDIA_ROOT", default=str(BASE_DIR / "media")))
STORAGES = {
    "default": {"BACKEND": "django.core.files.storage.FileSystemStorage"},
    "staticfiles": {
        "BACKEND": (
            "django.contrib.staticfiles.storage.StaticFilesStorage"
            if DEBUG
            else "whitenoise.storage.CompressedManifestStaticFilesStorage"
        )
    },
}

LOGIN_URL = "login"
LOGIN_REDIRECT_URL = "home"
LOGOUT_REDIRECT_URL = "login"

# Celery. No broker configured -> tasks run eagerly in-process (quick start).
_BROKER = env.str("CELERY_BROKER_URL", default="")
CELERY_BROKER_URL = _BROKER or "memory://"
CELERY_TASK_ALWAYS_EAGER = env.bool("CELERY_TASK_ALWAYS_EAGER", default=not _BROKER)
CELERY_TASK_EAGER_PROPAGATES = True
CELERY_RESULT_BACKEND = env.str("CELERY_RESULT_BACKEND", default="django-db")
CELERY_RESULT_EXTENDED = True
CELERY_ACCEPT_CONTENT = ["json"]
CELERY_TASK_SERIALIZER = "json"
CELERY_RESULT_SERIALIZER = "json"
CELERY_TIMEZONE = TIME_ZONE
CELERY_TASK_TIME_LIMIT = env.int("CELERY_TASK_TIME_LIMIT", default=30 * 60)
CELERY_TASK_SOFT_TIME_LIMIT = env.int("CELERY_TASK_SOFT_TIME_LIMIT", default=25 * 60)
CELERY_WORKER_PREFETCH_MULTIPLIER = 1
ANALYSIS_CHUNK_RESULTS = env.int("ANALYSIS_CHUNK_RESULTS", default=100_000)  # per chunk task
CELERY_BROKER_CONNECTION_RETRY_ON_STARTUP = True
# Lost jobs (README, "Lost workers"): a task working on an analysis run, a raw-data
# recomputation or a report batch writes a heartbeat every JOB_HEARTBEAT_SECONDS; a job
# silent for JOB_STALE_SECONDS is re-queued by the sweep (Celery beat, every JOB_SWEEP_SECONDS).
JOB_HEARTBEAT_SECONDS = env.float("JOB_HEARTBEAT_SECONDS", default=30.0)
JOB_STALE_SECONDS = max(env.float("JOB_STALE_SECONDS", default=300.0), 3 * JOB_HEARTBEAT_SECONDS)
JOB_SWEEP_SECONDS = env.float("JOB_SWEEP_SECONDS", default=60.0)
# After a run succeeds, a task draws the charts of a coordinator's first view of its charts
# page into the cache (docs/architecture.md §3.1); the tests turn it off (tests/conftest.py).
CHART_WARMING = env.bool("CHART_WARMING", default=True)
CHART_WARMING_SOFT_SECONDS = env.int("CHART_WARMING_SOFT_SECONDS", default=300)
# A round's archive (docs/interfaces.md §6) of a run with at most this many scores is built
# in the request that asks for it (a second or two); a larger one by a task.
ARCHIVE_INLINE_MAX_SCORES = env.int("ARCHIVE_INLINE_MAX_SCORES", default=5000)
# Redis: a task taken by a worker that dies (SIGKILL, power loss) is delivered again after
# the visibility timeout (acks_late).  The sweep recovers lost jobs within minutes; this
# redelivery is the backstop.  It must exceed the hard time limit of the longest task, else
# a task still running is delivered a second time.
_VISIBILITY = max(3600, CELERY_TASK_TIME_LIMIT) + 300
CELERY_BROKER_TRANSPORT_OPTIONS = {
    "visibility_timeout": env.int("CELERY_VISIBILITY_TIMEOUT", default=_VISIBILITY)
}
# Celery beat (exactly one per installation): daily housekeeping (labs.tasks, under its old
# name proficiency.tasks.housekeeping).
CELERY_BEAT_SCHEDULE = {
    "housekeeping": {
        "task": "proficiency.tasks.housekeeping",
        "schedule": crontab(hour=3, minute=17),
    },
    # reports of a publication whose enqueue was lost (broker down) are sent again
    "reports-pending": {"task": "analysis.tasks.reports_pending_task", "schedule": 300.0},
    # analysis runs, raw recomputations and report batches whose worker was lost are re-queued
    "jobs-sweep": {"task": "analysis.tasks.jobs_sweep_task", "schedule": JOB_SWEEP_SECONDS},
    # deadline reminders (Comparison.reminder_days; once per participant and day count), and
    # notices whose e-mail was not sent (broker down) sent again
    "notices-reminders": {"task": "labs.tasks.notices_reminders_task", "schedule": 3600.0},
}

API_BROWSABLE = env.bool("API_BROWSABLE", default=DEBUG)
# /api/schema/ and /api/docs/: public, or for signed-in people only (common.views)
API_DOCS_PUBLIC = env.bool("API_DOCS_PUBLIC", default=DEBUG)
REST_FRAMEWORK = {
    "EXCEPTION_HANDLER": "common.errors.api_exception_handler",
    "DEFAULT_AUTHENTICATION_CLASSES": [
        "rest_framework.authentication.SessionAuthentication",
    ],
    "DEFAULT_PERMISSION_CLASSES": ["rest_framework.permissions.IsAuthenticated"],
    "DEFAULT_SCHEMA_CLASS": "common.schema.AutoSchema",
    # the browsable API (HTML pages) only while developing, unless API_BROWSABLE says otherwise
    "DEFAULT_RENDERER_CLASSES": ["rest_framework.renderers.JSONRenderer"]
    + (["rest_framework.renderers.BrowsableAPIRenderer"] if API_BROWSABLE else []),
    # DRF's parsers, refusing control characters with a 400 naming the field
    "DEFAULT_PARSER_CLASSES": [
        "common.parsers.JSONParser",
        "common.parsers.FormParser",
        "common.parsers.MultiPartParser",
    ],
    "DEFAULT_FILTER_BACKENDS": ["common.filters.FilterBackend"],  # django-filter's
    "DEFAULT_PAGINATION_CLASS": "common.pagination.PageNumberPagination",  # DRF's
    "PAGE_SIZE": 100,
    "DEFAULT_THROTTLE_RATES": {
        "api_key": env.str("THROTTLE_API_KEY", default="600/min"),
        "user": env.str("THROTTLE_USER", default="600/min"),
        "anon": env.str("THROTTLE_ANON", default="60/min"),
    },
}

SPECTACULAR_SETTINGS = {
    "TITLE": "Proficiency testing API",
    "DESCRIPTION": (
        "Interlaboratory comparisons for accelerometer and IMU calibration. Lab software "
        "authenticates with `Authorization: Api-Key <key>`; browsers use the session."
    ),
    "VERSION": "1",
    # the publish answer holds two statuses (the comparison's, its publication job's): named
    "ENUM_NAME_OVERRIDES": {
        "ComparisonStatusEnum": "proficiency.models.ComparisonStatus",
        "PublicationStatusEnum": "analysis.models.Publication.Status",
    },
    "SERVE_INCLUDE_SCHEMA": False,
    "SWAGGER_UI_DIST": "SIDECAR",
    "SWAGGER_UI_FAVICON_HREF": "SIDECAR",
    "REDOC_DIST": "SIDECAR",
    "COMPONENT_SPLIT_REQUEST": True,
    "POSTPROCESSING_HOOKS": [
        "drf_spectacular.hooks.postprocess_schema_enums",
        "common.schema.error_responses",
    ],
}

# Uploads: refused above this size before parsing (docs/interfaces.md §1, issue rules).
MAX_UPLOAD_BYTES = env.int("MAX_UPLOAD_BYTES", default=5 * 1024 * 1024)
# Raw time series (docs/interfaces.md §2): per file, refused before the body is read.
RAW_UPLOAD_MAX_BYTES = env.int("RAW_UPLOAD_MAX_BYTES", default=50 * 1024 * 1024)
DATA_UPLOAD_MAX_MEMORY_SIZE = env.int("DATA_UPLOAD_MAX_MEMORY_SIZE", default=20 * 1024 * 1024)
FILE_UPLOAD_MAX_MEMORY_SIZE = 2 * 1024 * 1024
# Submissions: an Idempotency-Key is kept this long; identical results submitted again
# without a key within SUBMISSION_DEDUP_SECONDS answer the version already stored.
IDEMPOTENCY_KEY_HOURS = env.int("IDEMPOTENCY_KEY_HOURS", default=24)
SUBMISSION_DEDUP_SECONDS = env.int("SUBMISSION_DEDUP_SECONDS", default=600)

# PT provider shown on reports and pages; the title page of a report adds its address, its
# accreditation and its logo (a PNG or JPEG file; none, or a missing file: no logo).
PT_PROVIDER_NAME = env.str("PT_PROVIDER_NAME", default="Demo PT Provider")
PT_PROVIDER_ADDRESS = env.str("PT_PROVIDER_ADDRESS", default="1 Example Street, 12345 Example City")
PT_PROVIDER_ACCREDITATION = env.str(
    "PT_PROVIDER_ACCREDITATION", default="not accredited (a demonstration installation)"
)
PT_PROVIDER_LOGO = env.str("PT_PROVIDER_LOGO", default="")

# Security: strict when DEBUG is off (production); each can be overridden from the environment.
SECURE_PROXY_SSL_HEADER = ("HTTP_X_FORWARDED_PROTO", "https")
SECURE_SSL_REDIRECT = env.bool("SECURE_SSL_REDIRECT", default=not DEBUG)
SESSION_COOKIE_SECURE = env.bool("SESSION_COOKIE_SECURE", default=not DEBUG)
CSRF_COOKIE_SECURE = env.bool("CSRF_COOKIE_SECURE", default=not DEBUG)
SECURE_HSTS_SECONDS = env.int("SECURE_HSTS_SECONDS", default=0 if DEBUG else 31536000)
SECURE_HSTS_INCLUDE_SUBDOMAINS = not DEBUG
SECURE_HSTS_PRELOAD = not DEBUG
SECURE_CONTENT_TYPE_NOSNIFF = True
SECURE_REFERRER_POLICY = "same-origin"
SECURE_CROSS_ORIGIN_OPENER_POLICY = "same-origin"
# Health checks of a load balancer or of systemd come over plain HTTP on the host itself.
SECURE_REDIRECT_EXEMPT = [r"^healthz$"]
X_FRAME_OPTIONS = "DENY"
SESSION_COOKIE_HTTPONLY = True
SESSION_COOKIE_SAMESITE = "Lax"
CSRF_COOKIE_SAMESITE = "Lax"
# Only the site's own files (common.middleware). Inline SVG charts (matplotlib) need
# style attributes and one fixed <style> block (its hash); no inline or foreign script runs.
# Bootstrap draws form controls with data: SVG images.
_MATPLOTLIB_SVG_STYLE = (
    "sha256-"
    + base64.b64encode(
        hashlib.sha256(b"*{stroke-linejoin: round; stroke-linecap: butt}").digest()
    ).decode()
)
CONTENT_SECURITY_POLICY = env.str(
    "CONTENT_SECURITY_POLICY",
    default="; ".join(
        [
            "default-src 'self'",
            "script-src 'self'",
            f"style-src 'self' '{_MATPLOTLIB_SVG_STYLE}'",
            "style-src-attr 'unsafe-inline'",
            "img-src 'self' data:",
            "font-src 'self'",
            "connect-src 'self'",
            "object-src 'none'",
            "base-uri 'self'",
            "form-action 'self'",
            "frame-ancestors 'none'",
        ]
    ),
)
PERMISSIONS_POLICY = "camera=(), microphone=(), geolocation=(), payment=(), usb=()"

# Login lockout (django-axes): AXES_FAILURE_LIMIT failed sign-ins for one username from one
# address lock that pair for AXES_COOLOFF_TIME; the login page then answers 429.
AXES_FAILURE_LIMIT = env.int("LOGIN_FAILURE_LIMIT", default=5)
AXES_COOLOFF_TIME = timedelta(minutes=env.int("LOGIN_LOCKOUT_MINUTES", default=15))
AXES_LOCKOUT_PARAMETERS = [["username", "ip_address"]]
AXES_RESET_ON_SUCCESS = True
AXES_HTTP_RESPONSE_CODE = 429
AXES_LOCKOUT_TEMPLATE = "registration/locked_out.html"
AXES_CLIENT_IP_CALLABLE = "common.middleware.client_ip"
# Password reset (common.accounts): at most PASSWORD_RESET_LIMIT reset e-mails per
# client address and per e-mail address in PASSWORD_RESET_WINDOW; then 429.
PASSWORD_RESET_LIMIT = env.int("PASSWORD_RESET_LIMIT", default=5)
PASSWORD_RESET_WINDOW = timedelta(minutes=env.int("PASSWORD_RESET_WINDOW_MINUTES", default=60))
# Reverse proxies in front of gunicorn whose X-Forwarded-For is trusted (0: none).
TRUSTED_PROXY_COUNT = env.int("TRUSTED_PROXY_COUNT", default=0)

HEALTHZ_TIMEOUT = env.float("HEALTHZ_TIMEOUT", default=2.0)
# Sign-in records (django-axes AccessLog) kept this long, then removed by housekeeping.
LOGIN_LOG_RETENTION_DAYS = env.int("LOGIN_LOG_RETENTION_DAYS", default=365)

# Structured logs: JSON lines in production (common.logs), plain text while developing.
LOG_FORMAT = env.str("LOG_FORMAT", default="plain" if DEBUG else "json")
LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "formatters": {
        "plain": {"format": "%(asctime)s %(levelname)s %(name)s %(message)s"},
        "json": {"()": "common.logs.JsonFormatter"},
    },
    "handlers": {"console": {"class": "logging.StreamHandler", "formatter": LOG_FORMAT}},
    "root": {"handlers": ["console"], "level": env.str("LOG_LEVEL", default="INFO")},
}
# Celery worker and beat log through LOGGING too (one format for every process).
CELERY_WORKER_HIJACK_ROOT_LOGGER = False
