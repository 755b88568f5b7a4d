#!/usr/bin/env python3
"""Server time of the demo round's results and chart pages (target
< 300 ms each once the run's charts exist), and of the charts of a 1,000-laboratory
point (target < 1 s).

Builds the demo (``load_demo``) in a scratch SQLite database (or the database of
``DATABASE_URL``: give it one of its own, it is wiped), analyses and publishes it, then
requests every results page through Django's test client (the whole middleware stack) as
the coordinator and as a participant: first with the chart cache empty (the baseline,
measured in the same run), then again with the run's charts cached. Prints the median of
``-n`` requests per page, cold and warm, and the ratio; then a coordinator's first view of
the charts page cold and after the task that warms a new run's charts.

    .venv/bin/python bench/bench_pages.py -n 5
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-n", type=int, default=5, help="requests per page and state")
    parser.add_argument("--labs", type=int, default=1000, help="labs of the large point")
    args = parser.parse_args()
    scratch = tempfile.mkdtemp(prefix="pt-bench-pages-")
    os.environ.setdefault("DATABASE_URL", f"sqlite:///{scratch}/db.sqlite3")
    os.environ.setdefault("MEDIA_ROOT", f"{scratch}/media")
    os.environ["CELERY_TASK_ALWAYS_EAGER"] = "true"
    sys.path.insert(0, str(ROOT))
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")
    import django

    django.setup()
    from django.conf import settings

    settings.ALLOWED_HOSTS = ["*"]
    from django.core.cache import cache
    from django.core.management import call_command

    if "postgres" in os.environ["DATABASE_URL"]:
        call_command("flush", "--noinput", verbosity=0)
    call_command("migrate", "--noinput", verbosity=0)
    call_command("load_demo", verbosity=0)
    code, pages = _publish_demo()
    clients = _clients(code)
    print(f"demo round {code}: {sum(map(len, pages.values()))} pages, median of {args.n} requests")
    print(f"{'page':44} {'cold ms':>8} {'warm ms':>8} {'ratio':>6}")
    worst = 0.0
    for audience, client in clients.items():
        for page in pages[audience]:
            cold, warm = [], []
            for _ in range(args.n):
                cache.clear()
                cold.append(_time(client, page))
                warm.append(_time(client, page))
            c, w = statistics.median(cold), statistics.median(warm)
            worst = max(worst, w)
            print(f"{audience[:5] + ' ' + page[-38:]:44} {c:8.0f} {w:8.0f} {c / w:6.1f}")
    print(f"slowest warm page: {worst:.0f} ms (target < 300 ms)")
    _first_view(code, clients["coordinator"], args.n)
    _large(args.labs, args.n)


def _first_view(code: str, client, n: int) -> None:
    """A coordinator's first view of the charts page (no query) of a new run: cold, and
    after the background task that warms it (``charts_warm_task``, timed on its own)."""
    from django.core.cache import cache

    from analysis.chart_page import charts_warm
    from analysis.selectors import current_run
    from proficiency.models import Comparison

    run = current_run(Comparison.objects.get(code=code))
    assert run is not None
    page = f"/coordinator/{code}/charts/"
    cold, task, warmed = [], [], []
    for _ in range(n):
        cache.clear()
        cold.append(_time(client, page))
        cache.clear()
        start = time.perf_counter()
        assert charts_warm(run_id=run.pk)
        task.append((time.perf_counter() - start) * 1000)
        warmed.append(_time(client, page))
    c, t, w = (statistics.median(x) for x in (cold, task, warmed))
    print(
        f"first view of a new run's charts page (coordinator): cold {c:.0f} ms, "
        f"after the warming task {w:.0f} ms (the task: {t:.0f} ms, in the background)"
    )


def _time(client, path: str) -> float:
    start = time.perf_counter()
    response = client.get(path)
    elapsed = (time.perf_counter() - start) * 1000
    assert response.status_code == 200, (path, response.status_code)
    return elapsed


def _publish_demo():
    from analysis.models import AnalysisRun
    from analysis.services import analysis_run_start
    from proficiency.models import Comparison

    comparison = Comparison.objects.get(code="IMU-2024-DEMO")
    run = AnalysisRun.objects.filter(comparison=comparison, status="succeeded").first()
    if run is None:
        run = analysis_run_start(comparison=comparison, user=None)
    Comparison.objects.filter(pk=comparison.pk).update(status="published")
    from analysis.selectors import current_run

    run = current_run(comparison)
    assert run is not None
    first = run.assigned_values.order_by("pk").first()
    assert first is not None
    point = first.measurement_point_id
    c, p = f"/coordinator/{comparison.code}/", f"/results/{comparison.code}/"
    tail = ["scores/", "scores/?order=en", f"charts/?point={point}", "compatibility/",
            "compatibility/?factor=axis", "consistency/"]  # fmt: skip
    lab = comparison.participants.order_by("code").values_list("code", flat=True).first()
    downloads = [f"charts/{name}.{ext}?point={point}" for name in ("z", "en-bars", "youden")
                 for ext in ("svg", "png")]  # fmt: skip
    pages = {
        "coordinator": [c + "results/", c + "performance/", f"{c}performance/{lab}/"]
        + [c + t for t in tail]
        + [c + "charts/mandel-h.svg"],
        "participant": [p] + [p + t for t in tail] + [p + d for d in downloads] + ["/lab/history/"],
    }
    return comparison.code, pages


def _clients(code: str):
    from django.contrib.auth import get_user_model
    from django.test import Client

    from labs.models import Participant

    coordinator = Client()
    coordinator.force_login(get_user_model().objects.get(username="coordinator"))
    participant = Client()
    one = Participant.objects.filter(comparison__code=code).order_by("code").first()
    assert one is not None
    member = one.laboratory.members.first()
    assert member is not None
    participant.force_login(member.user)
    return {"coordinator": coordinator, "participant": participant}


def _large(labs: int, n: int) -> None:
    """The point charts of one point with ``labs`` results, drawn from plain data."""
    import numpy as np

    from analysis import charts

    rng = np.random.default_rng(1)
    codes = [f"L{i:04d}" for i in range(labs)]
    values = 100 + rng.normal(0, 0.5, labs)
    big_u = np.abs(rng.normal(1.0, 0.2, labs))
    en = (values - 100) / big_u
    times: dict[str, list[float]] = {"point": [], "en": []}
    for _ in range(n):
        start = time.perf_counter()
        charts.point_chart(codes, values.tolist(), big_u.tolist(), assigned_value=100.0,
                           assigned_expanded_uncertainty=0.1, title="large", unit="mV/(m/s²)",
                           highlight="L0007")  # fmt: skip
        times["point"].append(time.perf_counter() - start)
        start = time.perf_counter()
        charts.en_chart(codes, en.tolist(), title="En large", limit=1.0, highlight="L0007")
        times["en"].append(time.perf_counter() - start)
    for name, t in times.items():
        print(f"{labs}-lab {name} chart: {statistics.median(t) * 1000:.0f} ms (target < 1000 ms)")
    _large_standard(codes, values, big_u, en, n)


def _large_standard(codes, values, big_u, en, n: int) -> None:
    """The standard graphs (docs/domain.md §11.5) of the same thousand-lab point."""
    import numpy as np

    from analysis import standard_charts as sc

    rng = np.random.default_rng(2)
    other = values + rng.normal(0, 0.3, len(codes))
    builds = {
        "z": lambda: sc.z_chart(codes, (values - 100) / 0.5, title="z", highlight="L0007"),
        "en-bars": lambda: sc.en_bar_chart(codes, en, title="En", highlight="L0007"),
        "density": lambda: sc.density_chart(values, assigned_value=100.0,
                                            assigned_expanded_uncertainty=0.1, title="density",
                                            unit="mV/(m/s²)", own_value=float(values[7])),
        "doe": lambda: sc.doe_chart(codes, values - 100, big_u, title="DoE", unit="mV/(m/s²)",
                                    highlight="L0007"),
        "youden": lambda: sc.youden_chart(codes, values, other, assigned_x=100.0,
                                          assigned_y=100.0, x_label="a", y_label="b",
                                          unit="mV/(m/s²)", highlight="L0007"),
    }  # fmt: skip
    for name, build in builds.items():
        t = []
        for _ in range(n):
            start = time.perf_counter()
            build()
            t.append(time.perf_counter() - start)
        print(f"{len(codes)}-lab {name} chart: {statistics.median(t) * 1000:.0f} ms "
              "(target < 1000 ms)")  # fmt: skip


if __name__ == "__main__":
    main()
