"""Production mode: /healthz, the settings with DEBUG off, JSON logs, static files, make serve."""

import json
import logging
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from django.core.management import call_command
from django.db import OperationalError

from common import health
from common.logs import JsonFormatter

ROOT = Path(__file__).resolve().parents[2]
REDIS_URL = os.environ.get("CELERY_BROKER_URL", "")


def closed_port() -> int:
    """A local TCP port with nothing listening (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def production_env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("DEBUG", "SECURE_"))}
    env.update(DEBUG="false", SECRET_KEY="x" * 60 + "-test-production-key",
               ALLOWED_HOSTS="pt.example.org",
               EMAIL_URL="smtp+tls://pt:secret@mail.example.org:587")  # fmt: skip
    env.update(extra)
    return env


# --- /healthz ---------------------------------------------------------------------------------


@pytest.mark.django_db
def test_healthz_is_200_with_both_ok(client):
    response = client.get("/healthz")
    assert response.status_code == 200
    assert response.json() == {"database": "ok", "broker": "ok"}
    assert "no-store" in response["Cache-Control"]
    assert "sessionid" not in response.cookies and "csrftoken" not in response.cookies


@pytest.mark.django_db
@pytest.mark.skipif(not REDIS_URL.startswith("redis://"), reason="no Redis broker configured")
def test_healthz_reaches_a_real_redis_broker(client, settings):
    settings.CELERY_BROKER_URL = REDIS_URL
    response = client.get("/healthz")
    assert (response.status_code, response.json()) == (200, {"database": "ok", "broker": "ok"})


@pytest.mark.django_db
@pytest.mark.parametrize("scheme", ["redis", "amqp"])
def test_healthz_is_503_naming_the_broker_when_it_is_unreachable(client, settings, scheme):
    settings.CELERY_BROKER_URL = f"{scheme}://127.0.0.1:{closed_port()}/0"
    response = client.get("/healthz")
    assert response.status_code == 503
    assert response.json() == {"database": "ok", "broker": "error"}


@pytest.mark.django_db
def test_healthz_is_503_naming_the_database_and_leaks_no_reason(client, monkeypatch, caplog):
    class BrokenConnection:
        def cursor(self):
            raise OperationalError('password authentication failed for user "pt-secret-user"')

    monkeypatch.setattr(health, "connection", BrokenConnection())
    with caplog.at_level(logging.ERROR, logger="common.health"):
        response = client.get("/healthz")
    assert response.status_code == 503
    assert response.json() == {"database": "error", "broker": "ok"}
    assert b"pt-secret-user" not in response.content
    assert "pt-secret-user" in caplog.text  # the reason is logged for the operator


@pytest.mark.django_db
def test_healthz_needs_no_login_and_is_not_redirected_to_https(client, settings):
    settings.SECURE_SSL_REDIRECT = True
    assert client.get("/healthz").status_code == 200
    assert client.get("/accounts/login/").status_code == 301  # everything else goes to https


@pytest.mark.django_db
def test_healthz_accepts_only_get_and_head(client):
    assert client.head("/healthz").status_code == 200
    for method in (client.post, client.put, client.delete):
        assert method("/healthz").status_code == 405


# --- settings with DEBUG off ------------------------------------------------------------------

SHOW_SETTINGS = """
import json
from django.conf import settings as s
print(json.dumps({
    "debug": s.DEBUG, "ssl_redirect": s.SECURE_SSL_REDIRECT,
    "session_secure": s.SESSION_COOKIE_SECURE, "csrf_secure": s.CSRF_COOKIE_SECURE,
    "hsts": [s.SECURE_HSTS_SECONDS, s.SECURE_HSTS_INCLUDE_SUBDOMAINS, s.SECURE_HSTS_PRELOAD],
    "frame": s.X_FRAME_OPTIONS, "log_format": s.LOG_FORMAT,
    "static": s.STORAGES["staticfiles"]["BACKEND"],
    "backends": s.AUTHENTICATION_BACKENDS[0],
    "axes": "axes.middleware.AxesMiddleware" in s.MIDDLEWARE,
}))
"""


def test_production_settings_are_strict():
    result = subprocess.run(
        [sys.executable, "manage.py", "shell", "-c", SHOW_SETTINGS],
        cwd=ROOT, env=production_env(), capture_output=True, text=True, check=True,
    )  # fmt: skip
    shown = json.loads(result.stdout.strip().splitlines()[-1])
    assert shown == {
        "debug": False, "ssl_redirect": True, "session_secure": True, "csrf_secure": True,
        "hsts": [31536000, True, True], "frame": "DENY", "log_format": "json",
        "static": "whitenoise.storage.CompressedManifestStaticFilesStorage",
        "backends": "axes.backends.AxesStandaloneBackend", "axes": True,
    }  # fmt: skip


@pytest.mark.parametrize(
    ("email_url", "backend"),
    [
        (None, "django.core.mail.backends.console.EmailBackend"),
        ("smtp+tls://u:p@mail.example.org:587", "django.core.mail.backends.smtp.EmailBackend"),
    ],
)
def test_email_goes_to_the_console_unless_a_server_is_configured(email_url, backend):
    """Publishing sends e-mails: without a mail server configured they must not fail (the
    quick start's publication raised ConnectionRefusedError from the SMTP default)."""
    env = {k: v for k, v in os.environ.items() if k != "EMAIL_URL"}
    if email_url:
        env["EMAIL_URL"] = email_url
    show = "from django.conf import settings as s; print(s.EMAIL_BACKEND, s.EMAIL_HOST)"
    result = subprocess.run(
        [sys.executable, "manage.py", "shell", "-c", show],
        cwd=ROOT, env=env, capture_output=True, text=True, check=True,
    )  # fmt: skip
    shown = result.stdout.strip().splitlines()[-1].split()
    assert shown[0] == backend
    if email_url:
        assert shown[1] == "mail.example.org"


def test_rate_limit_counters_use_the_shared_cache_when_configured():
    """Without CACHE_URL each process counts throttled requests alone (found by the load
    test: 5 gunicorn workers allowed 5x the rate); with it, one Redis cache counts them."""
    env = {k: v for k, v in os.environ.items() if k != "CACHE_URL"}
    show = "from django.conf import settings as s; c = s.CACHES['default']; print(c['BACKEND'])"
    run = lambda e: subprocess.run(  # noqa: E731
        [sys.executable, "manage.py", "shell", "-c", show],
        cwd=ROOT, env=e, capture_output=True, text=True, check=True,
    ).stdout.strip().splitlines()[-1]  # fmt: skip
    assert run(env) == "django.core.cache.backends.locmem.LocMemCache"
    assert run(env | {"CACHE_URL": "redis://127.0.0.1:6379/2"}).endswith("RedisCache")


def test_check_deploy_is_clean_in_production_mode():
    result = subprocess.run(
        [sys.executable, "manage.py", "check", "--deploy", "--fail-level", "WARNING"],
        cwd=ROOT, env=production_env(), capture_output=True, text=True,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "System check identified no issues (0 silenced)." in result.stdout


def test_production_refuses_the_development_secret_key():
    env = production_env()
    env.pop("SECRET_KEY")
    result = subprocess.run(
        [sys.executable, "manage.py", "check"], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert result.returncode != 0
    assert "SECRET_KEY must be set when DEBUG is off." in result.stderr


@pytest.mark.parametrize("email_url", [None, "consolemail://", "filemail:///tmp/pt-mail"])
def test_production_refuses_an_email_backend_that_is_no_mail_server(email_url):
    """The console backend (the default) would print valid password reset links into the
    web log; with DEBUG off the service does not start without a mail server."""
    env = production_env()
    env.pop("EMAIL_URL")
    if email_url:
        env["EMAIL_URL"] = email_url
    result = subprocess.run(
        [sys.executable, "manage.py", "check"], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert result.returncode == 1
    assert "ImproperlyConfigured: EMAIL_URL must name a mail server when DEBUG is off" in (
        result.stderr
    )


@pytest.mark.parametrize(
    ("email_url", "backend"),
    [
        ("smtp://mail.example.org:25", "django.core.mail.backends.smtp.EmailBackend"),
        ("smtp+ssl://u:p@mail.example.org:465", "django.core.mail.backends.smtp.EmailBackend"),
        ("dummymail://", "django.core.mail.backends.dummy.EmailBackend"),  # sends nothing
    ],
)
def test_production_accepts_a_mail_server_or_sending_nothing(email_url, backend):
    show = "from django.conf import settings as s; print(s.EMAIL_BACKEND)"
    result = subprocess.run(
        [sys.executable, "manage.py", "shell", "-c", show],
        cwd=ROOT, env=production_env(EMAIL_URL=email_url), capture_output=True, text=True,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == backend


# --- the API in production: JSON only, documentation behind sign-in --------------------------

SHOW_API = """
import json
from django.test import Client
from rest_framework.settings import api_settings
browser = "text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8"
renderers = [r.__name__ for r in api_settings.DEFAULT_RENDERER_CLASSES]
c = Client(HTTP_HOST="pt.example.org")
# (the browsable pages need the collected static files: not asked for here)
one = len(renderers) == 1
api = c.get("/api/v1/comparisons/", HTTP_ACCEPT=browser, secure=True) if one else None
schema = c.get("/api/schema/?format=json", secure=True)
docs = c.get("/api/docs/", secure=True) if schema.status_code == 403 else None
print(json.dumps({
    "renderers": renderers,
    "api": api and [api.status_code, api["Content-Type"]],
    "schema": [schema.status_code, schema["Content-Type"]],
    "docs": docs and [docs.status_code, docs.get("Location", "")],
}))
"""


def show_api(**extra: str) -> dict:
    result = subprocess.run(
        [sys.executable, "manage.py", "shell", "-c", SHOW_API],
        cwd=ROOT, env=production_env(**extra), capture_output=True, text=True,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_production_api_has_no_browsable_pages_and_its_docs_need_sign_in():
    """A browser asking the API gets JSON (the browsable API's HTML pages showed forms and
    the parameters of every view); the schema and Swagger UI are for signed-in people."""
    assert show_api() == {
        "renderers": ["JSONRenderer"],
        "api": [401, "application/json"],
        "schema": [403, "application/json"],
        "docs": [302, "/accounts/login/?next=/api/docs/"],
    }


def test_production_api_browsable_pages_and_public_docs_when_configured():
    shown = show_api(API_BROWSABLE="true", API_DOCS_PUBLIC="true")
    assert shown["renderers"] == ["JSONRenderer", "BrowsableAPIRenderer"]
    assert shown["schema"] == [200, "application/vnd.oai.openapi+json"]


@pytest.mark.django_db
def test_api_docs_need_sign_in_unless_public(client, settings):
    from tests.factories import UserFactory

    settings.API_DOCS_PUBLIC = False
    refused = client.get("/api/schema/?format=json")
    assert refused.status_code == 403
    assert refused.json() == {"detail": "Sign in to read the API schema.", "errors": []}
    assert client.get("/api/docs/")["Location"] == "/accounts/login/?next=/api/docs/"
    client.force_login(UserFactory.create())
    assert client.get("/api/schema/?format=json").status_code == 200
    assert client.get("/api/docs/").status_code == 200
    client.logout()
    settings.API_DOCS_PUBLIC = True
    assert client.get("/api/schema/?format=json").status_code == 200


# --- structured logs --------------------------------------------------------------------------


def test_json_log_line_has_the_fields_extras_and_exception():
    logger = logging.getLogger("tests.production")
    try:
        raise ValueError("bad row 7")
    except ValueError:
        record = logger.makeRecord(
            logger.name, logging.ERROR, __file__, 1, "run %s failed", (42,), sys.exc_info(),
            extra={"run_id": 42, "comparison": "IMU-1"},
        )  # fmt: skip
    line = JsonFormatter().format(record)
    assert "\n" not in line
    entry = json.loads(line)
    assert entry["level"] == "ERROR" and entry["logger"] == "tests.production"
    assert entry["message"] == "run 42 failed"
    assert (entry["run_id"], entry["comparison"]) == (42, "IMU-1")
    assert entry["time"].endswith("+00:00")
    assert "ValueError: bad row 7" in entry["exception"]


# --- static files: collected, served by whitenoise --------------------------------------------


@pytest.mark.django_db
def test_collected_static_files_are_served_by_whitenoise(client, settings, tmp_path):
    settings.STATIC_ROOT = tmp_path / "static"
    settings.STORAGES = {
        **settings.STORAGES,
        "staticfiles": {"BACKEND": "django.contrib.staticfiles.storage.StaticFilesStorage"},
    }
    call_command("collectstatic", "--noinput", "-v", "0")
    settings.WHITENOISE_USE_FINDERS = False  # only what was collected
    settings.WHITENOISE_AUTOREFRESH = False
    response = client.get("/static/vendor/htmx/htmx.min.js")
    assert response.status_code == 200
    body = b"".join(response.streaming_content)
    assert body == (ROOT / "static/vendor/htmx/htmx.min.js").read_bytes()
    assert client.get("/static/js/site.js").status_code == 200


@pytest.mark.django_db
def test_media_files_are_never_served_by_url(client, settings):
    stored = Path(settings.MEDIA_ROOT) / "reports" / "IMU-1" / "secret.pdf"
    stored.parent.mkdir(parents=True)
    stored.write_bytes(b"%PDF-1.4 confidential")
    for url in ("/media/reports/IMU-1/secret.pdf", "/reports/IMU-1/secret.pdf"):
        response = client.get(url)
        assert response.status_code in (302, 404), url
        assert b"confidential" not in response.content


# --- make serve: the supervisor ---------------------------------------------------------------


def serve_module():
    sys.path.insert(0, str(ROOT / "deploy"))
    try:
        import serve
    finally:
        sys.path.pop(0)
    return serve


def test_serve_refuses_to_start_without_the_production_services(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DATABASE_URL", "CELERY_BROKER_URL")}
    env["SECRET_KEY"] = "s" * 60
    env.pop("ENV_FILE", None)
    result = subprocess.run(
        [sys.executable, "deploy/serve.py"], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert result.returncode == 1
    assert "set DATABASE_URL, CELERY_BROKER_URL" in result.stderr


def test_serve_reads_the_environment_file(tmp_path, monkeypatch):
    serve = serve_module()
    env_file = tmp_path / "env"
    env_file.write_text(
        "# comment\nSECRET_KEY='from-file'\nexport DATABASE_URL=postgres://db/pt\n"
        "CELERY_BROKER_URL=redis://broker/1\nDEBUG=true\n\n"
    )
    for name in ("SECRET_KEY", "DATABASE_URL", "CELERY_BROKER_URL", "DEBUG"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("ENV_FILE", str(env_file))
    monkeypatch.setenv("CELERY_BROKER_URL", "redis://from-environment/2")
    env = serve.environment()
    assert env["SECRET_KEY"] == "from-file" and env["DATABASE_URL"] == "postgres://db/pt"
    assert env["CELERY_BROKER_URL"] == "redis://from-environment/2"  # the environment wins
    assert env["DEBUG"] == "true"


def test_serve_runs_web_worker_beat_and_stops_all_when_one_dies(monkeypatch, tmp_path, capsys):
    serve = serve_module()
    up = tmp_path / "web-up"
    web = [sys.executable, "-c", "import sys, time; print('up', flush=True); "
           "open(sys.argv[1], 'a').close(); time.sleep(60)", str(up)]  # fmt: skip
    sleeper = [sys.executable, "-c", "import time; time.sleep(60)"]
    # beat dies only once web has printed its line (no race on a loaded machine)
    dying = [sys.executable, "-c", "import os, sys, time\n"
             "while not os.path.exists(sys.argv[1]): time.sleep(0.05)\n"
             "print('bye', flush=True); sys.exit(3)", str(up)]  # fmt: skip
    monkeypatch.setattr(
        serve, "commands", lambda state: {"web": web, "worker": sleeper, "beat": dying}
    )
    procs = serve.start(dict(os.environ), str(tmp_path))
    exited = serve.pump(procs, [False])
    serve.stop(procs)
    serve.drain(procs)
    assert exited == "beat" and procs["beat"].returncode == 3
    assert procs["web"].returncode == procs["worker"].returncode == -15  # SIGTERM
    out = capsys.readouterr().out
    assert "beat   | bye" in out and "web    | up" in out
    assert "serve | stopped (web -15, worker -15, beat 3)" in out


def test_gunicorn_config_has_at_least_two_workers_and_json_logs(monkeypatch):
    import runpy

    monkeypatch.setenv("WEB_CONCURRENCY", "1")
    config = runpy.run_path(str(ROOT / "deploy" / "gunicorn.conf.py"))
    assert config["workers"] == 2
    assert config["wsgi_app"] == "config.wsgi:application"
    # threaded workers without keep-alive (tests/proficiency/test_slow_clients.py)
    from gunicorn.workers.gthread import ThreadWorker

    assert issubclass(config["worker_class"], ThreadWorker)
    assert (config["threads"], config["keepalive"], config["READ_TIMEOUT"]) == (4, 0, 30.0)
    assert config["MIN_RATE"] == 10_000.0  # bytes per second a request must keep up
    formatter = config["logconfig_dict"]["formatters"]["json"]["()"]
    assert formatter == "common.logs.JsonFormatter"


def test_gunicorn_worker_freezes_what_start_up_allocated():
    """After the application is loaded, start-up objects leave the cyclic collector's
    generations (gc.freeze): full collections then walk only what requests allocate."""
    import gc
    import runpy

    config = runpy.run_path(str(ROOT / "deploy" / "gunicorn.conf.py"))
    before = gc.get_freeze_count()
    try:
        config["post_worker_init"](object())
        assert gc.get_freeze_count() > before
    finally:
        gc.unfreeze()


# --- beat: daily housekeeping -----------------------------------------------------------------


@pytest.mark.django_db
def test_housekeeping_deletes_only_what_expired_and_is_scheduled(settings):
    from datetime import timedelta

    from axes.models import AccessLog
    from django.contrib.sessions.models import Session
    from django.utils import timezone

    from config.celery import app
    from labs.tasks import housekeeping

    now = timezone.now()
    Session.objects.create(session_key="old", session_data="x", expire_date=now - timedelta(1))
    Session.objects.create(session_key="live", session_data="x", expire_date=now + timedelta(1))
    for days in (400, 10):
        log = AccessLog.objects.create(username="u", ip_address="127.0.0.1", user_agent="t")
        AccessLog.objects.filter(pk=log.pk).update(attempt_time=now - timedelta(days))
    assert housekeeping.delay().get() == {"sessions": 1, "login_records": 1, "submission_keys": 0}
    assert list(Session.objects.values_list("session_key", flat=True)) == ["live"]
    assert AccessLog.objects.count() == 1
    again = {"sessions": 0, "login_records": 0, "submission_keys": 0}
    assert housekeeping.delay().get() == again  # idempotent
    entry = settings.CELERY_BEAT_SCHEDULE["housekeeping"]
    assert entry["task"] in app.tasks


# --- RabbitMQ, once: a real worker takes a task from an AMQP broker ---------------------------

AMQP_URL = os.environ.get("TEST_AMQP_URL", "amqp://guest:guest@127.0.0.1:5672//")


def amqp_reachable() -> bool:
    from kombu import Connection

    try:
        with Connection(AMQP_URL, connect_timeout=2) as conn:
            conn.ensure_connection(max_retries=1)
        return True
    except Exception:
        return False


@pytest.mark.skipif(not amqp_reachable(), reason="no RabbitMQ at TEST_AMQP_URL")
def test_a_real_worker_runs_a_task_from_rabbitmq(tmp_path, monkeypatch):
    import uuid

    from celery import Celery

    queue = f"pt-test-{uuid.uuid4().hex[:8]}"
    env = {**os.environ, "CELERY_BROKER_URL": AMQP_URL, "CELERY_RESULT_BACKEND": "rpc://",
           "DATABASE_URL": f"sqlite:///{tmp_path / 'worker.sqlite3'}"}  # fmt: skip
    worker = subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "config", "worker", "-Q", queue,
         "-n", f"{queue}@%h", "-c", "1", "-P", "solo", "--without-gossip", "--without-mingle"],
        cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    monkeypatch.delenv("CELERY_BROKER_URL", raising=False)  # Celery lets it override broker=
    # not the current app: the service's tasks (shared_task) must stay bound to config.celery
    client = Celery(broker=AMQP_URL, backend="rpc://", set_as_current=False)
    try:
        result = client.send_task("celery.accumulate", args=(4, 2), queue=queue)
        assert result.get(timeout=60) == [4, 2]
    finally:
        worker.terminate()
        worker.wait(timeout=30)
        with client.connection_for_write() as conn:
            conn.default_channel.queue_delete(queue)  # leave the broker as it was
    assert worker.returncode == 0  # warm shutdown on SIGTERM
