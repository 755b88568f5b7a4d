"""The demo comparison, analysed: the data every report test builds on."""

import io
from io import StringIO

import pytest
from django.core.management import call_command

from analysis.selectors import current_run
from analysis.services import analysis_run_start
from proficiency.models import Comparison

CODE = "IMU-2024-DEMO"


@pytest.fixture
def demo():
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    return Comparison.objects.get(code=CODE)


@pytest.fixture
def analysed(demo):
    """The demo after one analysis run (eager Celery; needs a transactional test)."""
    analysis_run_start(comparison=demo, user=None)
    demo.refresh_from_db()
    run = current_run(demo)
    assert run is not None
    return run


@pytest.fixture(autouse=True)
def media_root(settings, tmp_path):
    """Issued reports go to a temporary MEDIA_ROOT, never into the working tree."""
    settings.MEDIA_ROOT = tmp_path / "media"
    return settings.MEDIA_ROOT


def pdf_text(pdf: bytes) -> list[str]:
    """The text of each page (pypdf)."""
    from pypdf import PdfReader

    return [page.extract_text() for page in PdfReader(io.BytesIO(pdf)).pages]


def published_missing_reports(comparison):
    """``comparison`` published without its final reports, the state the report fan-out
    (``reports_issue_all_task``, sent again by beat) completes: a round published before
    publication rendered its reports itself.  Set as that publication did: the status,
    every preliminary report superseded, no final one (and no notice)."""
    from django.db import transaction

    from analysis.reports.services import reports_preliminary_supersede
    from proficiency.services import comparison_transition

    with transaction.atomic():
        published = comparison_transition(comparison=comparison, to="published")
        reports_preliminary_supersede(comparison=published)
    return published


def pdftotext(pdf: bytes, tmp_path, first: int | None = None, last: int | None = None) -> str:
    """poppler's ``pdftotext -layout`` of pages ``first`` to ``last`` (all by default)."""
    import subprocess

    path = tmp_path / "report-for-text.pdf"
    path.write_bytes(pdf)
    pages = [*(["-f", str(first)] if first else []), *(["-l", str(last)] if last else [])]
    done = subprocess.run(
        ["pdftotext", "-layout", *pages, str(path), "-"], check=True, capture_output=True
    )
    return done.stdout.decode("utf8")


def page_count(pdf: bytes, tmp_path) -> int:
    """The number of pages, from poppler's ``pdfinfo``."""
    import re
    import subprocess

    path = tmp_path / "report-for-info.pdf"
    path.write_bytes(pdf)
    info = subprocess.run(["pdfinfo", str(path)], check=True, capture_output=True).stdout
    found = re.search(rb"^Pages:\s+(\d+)", info, re.M)
    assert found is not None
    return int(found.group(1))
