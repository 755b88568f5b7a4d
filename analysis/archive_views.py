"""The round's archive on the results pages (both audiences, as ``analysis.views``): the
"Download everything (ZIP)" button (POST), its status line (polled by htmx while the ZIP
is built) and the download of the ready file.  Who may read which archive is who may read
the results page: the round's coordinators (any successful run), a participant once
published (the current run, its own archive); everyone else gets 404."""

from __future__ import annotations

from typing import TYPE_CHECKING

from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.http import FileResponse, Http404, HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.views.decorators.http import require_GET, require_POST

from analysis.archive import archive_filename, archive_of, archive_request
from analysis.models import RoundArchive
from analysis.selectors import current_run
from analysis.views import COORDINATOR, Viewer, _chosen_run, archive_context
from common.errors import ApplicationError
from labs.access import coordinated, published_participation
from labs.models import Participant

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest


def _reader(
    request: AuthenticatedHttpRequest, code: str, audience: str, run_id: str
) -> tuple[Viewer, Participant | None]:
    """The viewer of the archive's run and whose archive it is (None: the coordinators');
    404 for anyone who may not read the results page."""
    if audience == COORDINATOR:
        comparison = coordinated(request, code)
        return Viewer(comparison, _chosen_run(comparison, run_id), audience), None
    participant = published_participation(request, code)
    run = current_run(participant.comparison)
    return Viewer(participant.comparison, run, audience, own_code=participant.code), participant


@login_required
@require_POST
def archive_ask(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    """Ask for the run's archive (``run``: a coordinator's run shown); built here for a
    small round, else queued.  htmx gets the status line, a form post the results page."""
    viewer, participant = _reader(request, code, audience, request.POST.get("run", ""))
    if viewer.run is None:
        raise Http404(f"{code} has no analysed results yet.")
    try:
        archive = archive_request(comparison=viewer.comparison, run=viewer.run,
                                  participant=participant, user=request.user)  # fmt: skip
    except ApplicationError as exc:
        messages.error(request, exc.message)
        return redirect(viewer.url("results"))
    if getattr(request, "htmx", False):
        return _status(request, viewer, archive)
    return redirect(viewer.url("results"))


@login_required
@require_GET
def archive_status(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    """The status line, polled by htmx while the archive is queued or running."""
    viewer, participant = _reader(request, code, audience, request.GET.get("run", ""))
    if viewer.run is None:
        raise Http404(f"{code} has no analysed results yet.")
    return _status(request, viewer, archive_of(viewer.run, participant))


def _status(request: HttpRequest, viewer: Viewer, archive: RoundArchive | None) -> HttpResponse:
    context = {"comparison": viewer.comparison, "run": viewer.run, "viewer": viewer,
               **archive_context(viewer, archive)}  # fmt: skip
    return render(request, "analysis/_archive.html", context)


@login_required
@require_GET
def archive_download(
    request: AuthenticatedHttpRequest, code: str, run: int, audience: str
) -> FileResponse:
    """The ready ZIP of run ``run`` for the reader, as an attachment ``<round>-run<N>.zip``;
    404 when there is none ready (or the reader may not read that run)."""
    viewer, participant = _reader(request, code, audience, str(run))
    if viewer.run is None or viewer.run.pk != run:
        raise Http404(f"No archive of run {run} of {code} is visible to you.")
    archive = archive_of(viewer.run, participant)
    if archive is None or archive.status != RoundArchive.Status.READY or not archive.file:
        raise Http404(f"No archive of run {run} of {code} is ready; ask for it first.")
    archive.run = viewer.run  # for its file name, read already
    response = FileResponse(
        archive.file.open("rb"), as_attachment=True, filename=archive_filename(archive),
        content_type="application/zip",
    )  # fmt: skip
    response["Cache-Control"] = "private, no-store"
    return response
