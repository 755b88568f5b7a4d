"""The Celery app of the fault tests' workers: the project's app plus one test-only fault.

With ``FAULT_HANG_CHUNK=i`` the worker hangs inside chunk ``i``'s transaction (``run``:
inside the single task of a one-chunk run), after its
assigned values and scores are written and before they commit, and writes the file
``FAULT_MARKER`` (the pid of the process that hangs) so that the test knows when to
SIGKILL it, in the solo pool's process or a prefork child; with ``FAULT_READY`` it
writes that file when it is ready to consume.  With ``FAULT_HANG_REPORT=<participant
code>`` it hangs likewise while rendering that participant's report, inside the report's
transaction.  Nothing of this is in
the project's code: the worker is started with ``-A tests.faults.worker_app``.
"""

import os
import time
from pathlib import Path
from typing import Any

from celery.signals import task_prerun, worker_process_init, worker_ready

from config.celery import app

__all__ = ["app"]
# tasks sent by the worker itself (a chord, a report group) go to the test's queue too
app.conf.task_default_queue = os.environ.get("FAULT_QUEUE", app.conf.task_default_queue)
_current: dict[str, object] = {}


@task_prerun.connect
def _remember(task=None, args=None, **_: object) -> None:
    _current["task"], _current["args"] = getattr(task, "name", ""), tuple(args or ())


@worker_ready.connect
def _ready(**_: object) -> None:
    if ready := os.environ.get("FAULT_READY"):  # tells the test when this worker consumes
        Path(ready).write_text(str(time.time()))
    _install_hang()  # the solo pool runs tasks in this (the main) process


@worker_process_init.connect
def _in_child(**_: object) -> None:
    _install_hang()  # a prefork child: forked before worker_ready, so patched here too


def _install_hang() -> None:
    _install_report_hang()
    import analysis.services as services

    hang = os.environ.get("FAULT_HANG_CHUNK")  # a chunk index, or "run": the single task
    if not hang:
        return
    original = services.write_scores

    def hangs_here() -> bool:
        if hang == "run":
            return _current.get("task") == "analysis.tasks.analysis_run_task"
        chunk = _current.get("task") == "analysis.tasks.analysis_chunk_task"
        return chunk and int(_current["args"][1]) == int(hang)  # type: ignore[index]

    def write_scores(*args: Any, **kwargs: Any) -> int:
        out = original(*args, **kwargs)
        if hangs_here():
            Path(os.environ["FAULT_MARKER"]).write_text(f"{time.time()} {os.getpid()}")
            time.sleep(600)  # killed by the test long before
        return out

    if not getattr(services.write_scores, "hangs", False):
        write_scores.hangs = True  # type: ignore[attr-defined]
        services.write_scores = write_scores


def _install_report_hang() -> None:
    import analysis.reports.services as services

    code = os.environ.get("FAULT_HANG_REPORT")
    if not code or getattr(services.render_report, "hangs", False):
        return
    original = services.render_report

    def render_report(data: Any) -> bytes:
        if data.own_code == code:
            Path(os.environ["FAULT_MARKER"]).write_text(f"{time.time()} {os.getpid()}")
            time.sleep(600)  # killed by the test long before
        return original(data)

    render_report.hangs = True  # type: ignore[attr-defined]
    services.render_report = render_report
