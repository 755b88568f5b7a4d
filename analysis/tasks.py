"""Celery tasks of the analysis side. Tasks take ids and re-check state (safe to run twice).

An analysis run is ``analysis_run_task`` (claim, plan the chunks; a small round is
analysed right there), or, for a large round, one ``analysis_chunk_task`` per chunk of
measurement points, the chunk that stores the last one sending ``analysis_finish_task``
(compatibility matrices, run done).  ``acks_late`` with ``reject_on_worker_lost``: a
task lost with a pool process is delivered again at once and takes its claim over.
When the whole worker is lost, ``jobs_sweep_task`` (Celery beat) re-queues the work
whose heartbeat went stale, within minutes; the broker's visibility timeout is the
backstop.  A chunk already stored, or held by a live task, is a no-op.
"""

import logging

from celery import shared_task
from celery.exceptions import SoftTimeLimitExceeded
from django.conf import settings

from analysis.reports.tasks import (  # noqa: F401
    report_issue_batch_task,
    report_issue_task,
    reports_issue_all_task,
)

log = logging.getLogger(__name__)
_TASK = {
    "acks_late": True,
    "reject_on_worker_lost": True,
    "soft_time_limit": settings.CELERY_TASK_SOFT_TIME_LIMIT,
    "time_limit": settings.CELERY_TASK_TIME_LIMIT,
}


@shared_task(bind=True, **_TASK)
def analysis_run_task(self, run_id: int) -> str:
    """Execute analysis run ``run_id`` (claimed with a conditional update); its chunks go
    to the queue this task came from."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.services import analysis_run_execute

    queue = (self.request.delivery_info or {}).get("routing_key")
    return analysis_run_execute(run_id=run_id, queue=queue, delivery=self.request.id or "")


@shared_task(bind=True, **_TASK)
def analysis_chunk_task(self, run_id: int, index: int) -> str:
    """Analyse chunk ``index`` of run ``run_id`` and store its outputs; the last chunk
    stored sends the final step to the queue this task came from."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.services import analysis_chunk_execute

    queue = (self.request.delivery_info or {}).get("routing_key")
    return analysis_chunk_execute(
        run_id=run_id, index=index, delivery=self.request.id or "", queue=queue
    )


@shared_task(**_TASK)
def analysis_finish_task(run_id: int) -> str:
    """The chord body: compatibility matrices of run ``run_id``, then mark it done."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.services import analysis_run_finish

    return analysis_run_finish(run_id=run_id)


@shared_task(
    soft_time_limit=settings.CHART_WARMING_SOFT_SECONDS,
    time_limit=settings.CHART_WARMING_SOFT_SECONDS + 60,
)
def charts_warm_task(run_id: int) -> bool:
    """Draw run ``run_id``'s charts of a coordinator's first view into the chart cache
    (docs/architecture.md §3.1); a chart already cached is not drawn again, so a second
    delivery draws nothing.  Past the soft limit it stops: the page draws the rest."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.chart_page import charts_warm

    try:
        return charts_warm(run_id=run_id)
    except SoftTimeLimitExceeded:
        log.warning("charts of analysis run %s: warming stopped at the soft time limit", run_id)
        return False


@shared_task(bind=True, **_TASK)
def publication_task(self, publication_id: int) -> str:
    """Publish: claim publication ``publication_id``, render every final report, then
    publish in one transaction (or fail, publishing nothing); its status at the end."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.publication import publication_execute

    return publication_execute(publication_id=publication_id, delivery=self.request.id or "")


@shared_task(bind=True, **_TASK)
def archive_build_task(self, archive_id: int) -> str:
    """Build and store the ZIP of archive ``archive_id`` (claimed with a conditional update;
    a row already ready is left as it is); its status at the end."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.archive import archive_execute

    return archive_execute(archive_id=archive_id, delivery=self.request.id or "")


@shared_task(soft_time_limit=120, time_limit=180)
def reports_pending_task() -> int:
    """Celery beat: queue the reports of published comparisons that still miss some."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.reports.services import reports_pending_enqueue

    return reports_pending_enqueue()


@shared_task(soft_time_limit=50, time_limit=60)
def jobs_sweep_task() -> dict[str, int]:
    """Celery beat (``JOB_SWEEP_SECONDS``): re-queue analysis runs, raw-data recomputations,
    report batches, publications and round archives whose worker was lost (heartbeat older than
    ``JOB_STALE_SECONDS``) or whose message was; the counts of tasks sent."""
    # in the body: the service modules import this one to enqueue the task (a cycle)
    from analysis.archive import archives_sweep
    from analysis.publication import publications_sweep
    from analysis.reports.services import report_batches_sweep
    from analysis.services import analysis_sweep
    from labs.raw_services import raw_sweep

    return analysis_sweep() | {
        "raw": raw_sweep(),
        "reports": report_batches_sweep(),
        "publications": publications_sweep(),
        "archives": archives_sweep(),
    }
