"""CPU of one participant report in-process (a script, not a test), on a round
kept by ``bench_scale.py --keep``:

    DATABASE_URL=postgres://postgres@127.0.0.1:5432/<scratch-db>_10000x100 \\
        .venv/bin/python bench/bench_report_cpu.py [--reports 100] [--profile OUT.prof]

After a warm-up batch of one report (the run's shared data and every chart of the
round, as a worker's first batch builds them; timed apart), the same seeded sample of
participants as ``bench_scale.py`` is issued through ``report_issue_batch`` in batches of
25 (queries, PDF, file, row: what a worker does), then rendered again without the
database (``report_data`` + ``render_report``: the renderer alone), each report's
process CPU time (``time.process_time``) averaged.  The reports made are deleted and
files go to a temporary MEDIA_ROOT.  ``--profile`` writes a cProfile of the batches.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import random
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CODE = "BENCH-SCALE"


def setup() -> None:
    sys.path.insert(0, str(ROOT))
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")
    os.environ.setdefault("DEBUG", "false")
    os.environ.setdefault("EMAIL_URL", "dummymail://")  # DEBUG off needs one; send nothing
    os.environ.setdefault("SECRET_KEY", "bench-only-not-a-secret-bench-only-not-a-secret")
    import django

    django.setup()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reports", type=int, default=100, help="sampled participants")
    ap.add_argument("--profile", help="write a cProfile of the batches here")
    args = ap.parse_args()
    media = tempfile.mkdtemp(prefix="bench-report-cpu-")
    os.environ["MEDIA_ROOT"] = media
    setup()
    try:
        measure(args.reports, args.profile)
    finally:
        shutil.rmtree(media, ignore_errors=True)


def measure(k: int, profile: str | None) -> None:
    from analysis.models import AnalysisRun, Report
    from analysis.reports.assemble import report_data
    from analysis.reports.render import render_report
    from analysis.reports.services import report_batches, report_issue_batch
    from labs.models import Participant
    from proficiency.models import Comparison

    comparison = Comparison.objects.get(code=CODE)
    Report.objects.filter(comparison=comparison).delete()
    run_id, batches = report_batches(comparison)
    ids = [pk for batch in batches for pk in batch]
    chosen = set(random.Random(9).sample(ids, min(k + 1, len(ids))))  # as bench_scale
    ids = [pk for pk in ids if pk in chosen]
    started = time.process_time()
    report_issue_batch(run_id=run_id, participant_ids=ids[:1])
    print(f"{len(chosen) - 1} of {sum(map(len, batches)):,} participants; warm-up batch of one "
          f"report: {time.process_time() - started:.1f} s CPU", flush=True)  # fmt: skip
    rest, prof = ids[1:], cProfile.Profile() if profile else None
    started = time.process_time()
    if prof:
        prof.enable()
    for i in range(0, len(rest), 25):
        report_issue_batch(run_id=run_id, participant_ids=rest[i : i + 25])
    if prof:
        prof.disable()
        assert profile  # prof exists only when a path was given
        prof.dump_stats(profile)
    issued = (time.process_time() - started) / len(rest)
    run = AnalysisRun.objects.select_related("comparison").get(pk=run_id)
    started = time.process_time()
    for p in Participant.objects.filter(pk__in=rest):
        render_report(report_data(run=run, participant=p))
    rendered = (time.process_time() - started) / len(rest)
    print(f"per report: {issued * 1000:.0f} ms CPU issued through the batch service, "
          f"{rendered * 1000:.0f} ms rendered alone (with its own rows' query); "
          f"load {os.getloadavg()[0]:.2f}")  # fmt: skip
    Report.objects.filter(comparison=comparison).delete()


if __name__ == "__main__":
    main()
