"""Shared fixtures. Factories are imported inside the fixtures so that the Django-free
tests (tests/analysis/core, tests/labs/test_importers.py) also run with ``-p no:django``."""

import os

import pytest
from hypothesis import settings as hypothesis_settings

# CI explores a fixed set of examples (a submission must not fail on a new random draw);
# local runs keep exploring new ones, and what they find becomes an explicit test.
hypothesis_settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    hypothesis_settings.load_profile("ci")


#: the modules that take longest (half a minute to two on a worker: real workers, browsers,
#: gunicorn and subprocesses, fuzzing, every route by every persona), run first: the two
#: xdist workers then end on short tests, together, instead of one waiting for the other's
#: last long test (longest first); the order within a module stays
LONGEST_FIRST = (
    "tests/security/test_schema_fuzz.py",
    "tests/faults/",
    "tests/proficiency/test_production.py",
    "tests/security/test_permission_matrix.py",
    "tests/proficiency/test_slow_clients.py",
    "tests/browser/",
)


@pytest.hookimpl(trylast=True)  # after pytest-django's order (its TestCase tests first)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    def rank(item: pytest.Item) -> int:
        found = (i for i, prefix in enumerate(LONGEST_FIRST) if item.nodeid.startswith(prefix))
        return next(found, len(LONGEST_FIRST))

    items.sort(key=rank)  # stable: every module keeps its tests together and in order


#: kept by the flush after a transactional test: post_migrate would write the same rows again
FLUSH_KEEPS = frozenset({"django_content_type", "auth_permission"})


@pytest.fixture(autouse=True, scope="session")
def flush_by_delete(request):
    """A transactional test (``transaction=True``, a live server, a real worker) ends with
    Django's flush, on PostgreSQL a TRUNCATE of every table: about 1.5 s each time, as
    PostgreSQL gives every table and index new files; DELETE of the few rows a test wrote
    takes milliseconds and leaves the same empty tables (sequences run on either way). The
    foreign keys are deferred to the end of the flush's transaction, so no order is needed.
    Content types and permissions stay: post_migrate, which follows the flush, would only
    write them again."""
    if not request.config.pluginmanager.hasplugin("django"):
        yield
        return
    from django.db.backends.postgresql.operations import DatabaseOperations

    truncate = DatabaseOperations.sql_flush

    def sql_flush(self, style, tables, *, reset_sequences=False, allow_cascade=False):
        if reset_sequences or allow_cascade:  # TRUNCATE's own options: Django's statement
            return truncate(self, style, tables, reset_sequences=reset_sequences,
                            allow_cascade=allow_cascade)  # fmt: skip
        deletes = [f"DELETE FROM {self.quote_name(t)}" for t in tables if t not in FLUSH_KEEPS]
        return ["SET CONSTRAINTS ALL DEFERRED", *deletes] if deletes else []

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(DatabaseOperations, "sql_flush", sql_flush)
        yield


@pytest.fixture(autouse=True)
def fast_password_hasher(request):
    """Password hashing is deliberately slow; tests do not need that strength."""
    if "settings" not in request.fixturenames and not request.config.pluginmanager.hasplugin(
        "django"
    ):
        return
    settings = request.getfixturevalue("settings")
    settings.PASSWORD_HASHERS = ["django.contrib.auth.hashers.MD5PasswordHasher"]


@pytest.fixture(autouse=True)
def celery_eager(request):
    """Tasks run in-process unless a test asks for the real worker (``real_worker`` mark),
    also when CELERY_BROKER_URL points at a real broker (as in CI)."""
    if "real_worker" in request.keywords or not request.config.pluginmanager.hasplugin("django"):
        yield
        return
    from config.celery import app

    old = app.conf.task_always_eager
    app.conf.task_always_eager = True
    yield
    app.conf.task_always_eager = old


@pytest.fixture(autouse=True)
def isolated_media_root(request, tmp_path):
    """Uploaded files and issued reports go to a temporary folder, not the project's media/."""
    if not request.config.pluginmanager.hasplugin("django"):
        return
    settings = request.getfixturevalue("settings")
    settings.MEDIA_ROOT = tmp_path / "media"


@pytest.fixture(autouse=True)
def chart_warming_off(request):
    """No chart warming after a run (docs/architecture.md §3.1): eager, it would draw a dozen
    charts, seconds, in every test that runs an analysis; its own test turns it on."""
    if not request.config.pluginmanager.hasplugin("django"):
        return
    request.getfixturevalue("settings").CHART_WARMING = False


@pytest.fixture(autouse=True)
def demo_without_earlier_round(request, monkeypatch):
    """The demo loads without its published earlier round, IMU-2023-DEMO, whose analysis and
    publication (13 PDF reports, at commit) would cost every test that loads the demo seconds
    and add rows to what it counts; a test of that round asks for ``demo_earlier_round``."""
    if not request.config.pluginmanager.hasplugin("django"):
        return
    monkeypatch.setattr("coordination.demo.EARLIER_ROUND", False)


@pytest.fixture(autouse=True)
def demo_kits_without_drift(request, monkeypatch):
    """The demo's Kit B does not drift: the pilot's repeats of both kits only scatter, so no
    slope is significant and a run of the demo scores as the offline tool, which knows no
    kits (docs/domain.md §13); a test of the drift asks for ``demo_kit_drift``."""
    if not request.config.pluginmanager.hasplugin("django"):
        return
    monkeypatch.setattr("coordination.demo.KITS", (("Kit A", "A", 0.0), ("Kit B", "B", 0.0)))


@pytest.fixture
def demo_kit_drift(monkeypatch):
    """``load_demo`` makes Kit B's MEMS 1 drift, as ``make run`` does."""
    from coordination import demo

    monkeypatch.setattr("coordination.demo.KITS", demo.DEMO_KITS)


@pytest.fixture(autouse=True)
def demo_without_kits_round(request, monkeypatch):
    """The demo loads without IMU-2025-KITS, whose analysis run would cost every test that
    loads the demo a second and add rows to what it counts; a test of that round asks for
    ``demo_kits_round``."""
    if not request.config.pluginmanager.hasplugin("django"):
        return
    monkeypatch.setattr("coordination.demo.KITS_ROUND", False)


@pytest.fixture
def demo_kits_round(monkeypatch):
    """``load_demo`` makes IMU-2025-KITS too, as ``make run`` does."""
    monkeypatch.setattr("coordination.demo.KITS_ROUND", True)


@pytest.fixture
def demo_earlier_round(monkeypatch):
    """``load_demo`` makes the earlier round too, as ``make run`` does."""
    monkeypatch.setattr("coordination.demo.EARLIER_ROUND", True)


@pytest.fixture
def comparison(db):
    from tests.factories import ComparisonFactory

    return ComparisonFactory.create()


@pytest.fixture
def device(comparison):
    from tests.factories import DeviceFactory

    return DeviceFactory.create(comparison=comparison)


@pytest.fixture
def point(device):
    from tests.factories import MeasurementPointFactory

    return MeasurementPointFactory.create(device=device)


@pytest.fixture
def needs_postgres():
    """Tests of row locks between connections, heartbeats and NUL storage need PostgreSQL
    (CI sets it): skipped loudly without it, a failure under ``REQUIRE_SERVICES=1``."""
    from django.db import connection

    if connection.vendor == "postgresql":
        return
    message = f"POSTGRESQL TEST NOT RUN: the database is {connection.vendor}, not PostgreSQL"
    if os.environ.get("REQUIRE_SERVICES") == "1":
        pytest.fail(message)
    pytest.skip(message)


def stand_in_pdf_bytes(data) -> bytes:
    """A stand-in for a report's PDF: its report number (with its edition, ``-v2``), status
    and count of result rows, readable in the stored file."""
    return f"%PDF-1.4 stand-in {data.report_number} {data.status} {len(data.results)}".encode()


@pytest.fixture
def stand_in_pdf(monkeypatch) -> None:
    """Reports issued with :func:`stand_in_pdf_bytes` instead of reportlab's rendering (a
    second or so a report): for the tests that need reports to exist (rows, files, access,
    fan-out) and never read their pages. The rendering itself is checked by the tests that
    read the PDFs' text (tests/analysis/reports)."""
    use_stand_in_pdf(monkeypatch)


def use_stand_in_pdf(monkeypatch: pytest.MonkeyPatch) -> None:
    """From here on in the test, reports are issued with :func:`stand_in_pdf_bytes`."""
    monkeypatch.setattr("analysis.reports.services.render_report", stand_in_pdf_bytes)
