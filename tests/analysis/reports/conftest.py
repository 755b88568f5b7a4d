"""The demo comparison, analysed: the data every report test builds on."""

import io
from collections.abc import Sequence
from typing import overload

import pytest

from analysis.selectors import current_run
from analysis.services import analysis_run_start

CODE = "IMU-2024-DEMO"


@pytest.fixture
def analysed(demo):
    """The demo after one analysis run (eager Celery; needs a transactional test)."""
    analysis_run_start(comparison=demo, user=None)
    demo.refresh_from_db()
    run = current_run(demo)
    assert run is not None
    return run


def words(text: str) -> str:
    """``text`` with every run of white space (a line break of the PDF) one space."""
    return " ".join(text.split())


@pytest.fixture(autouse=True)
def media_root(settings, tmp_path):
    """Issued reports go to a temporary MEDIA_ROOT, never into the working tree."""
    settings.MEDIA_ROOT = tmp_path / "media"
    return settings.MEDIA_ROOT


class PdfPages(Sequence[str]):
    """The text of each page (pypdf), extracted when first read: ``pdf_text(pdf)[0]`` reads
    the first page only (pypdf takes a fifth of a second per page of a report)."""

    def __init__(self, pdf: bytes) -> None:
        from pypdf import PdfReader

        self._pages = PdfReader(io.BytesIO(pdf)).pages
        self._text: dict[int, str] = {}

    def __len__(self) -> int:
        return len(self._pages)

    @overload
    def __getitem__(self, i: int) -> str: ...
    @overload
    def __getitem__(self, i: slice) -> list[str]: ...
    def __getitem__(self, i: int | slice) -> str | list[str]:
        if isinstance(i, slice):
            return [self[j] for j in range(len(self))[i]]
        j = range(len(self))[i]  # an IndexError past the end, as a list's
        if j not in self._text:
            self._text[j] = self._pages[j].extract_text()
        return self._text[j]


def pdf_text(pdf: bytes) -> PdfPages:
    """The text of each page (pypdf), each page read when first asked for."""
    return PdfPages(pdf)


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
