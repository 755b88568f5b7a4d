"""Charts of a run drawn once: the SVG text cached per analysis run (docs/architecture.md,
"Chart cache").

A succeeded run never changes (a new analysis is a new run), so a chart keyed by the run,
the chart's name and everything else it is drawn from (the point, the reader's own code,
the En limit) is valid as long as the run exists; a new run has new keys, so nothing has
to be invalidated, and the entries of a deleted or old run expire.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Hashable
from pathlib import Path
from typing import TypeVar

from django.core.cache import cache

from analysis import charts, score_charts, standard_charts
from analysis.models import AnalysisRun

T = TypeVar("T")
TIMEOUT = 7 * 24 * 3600  # seconds; entries of runs nobody reads any more fall out
#: the drawing code's own digest: a deployment that changes how charts look gets new keys
VERSION = hashlib.sha256(
    b"".join(Path(str(m.__file__)).read_bytes() for m in (charts, score_charts, standard_charts))
).hexdigest()[:12]


def chart_key(run: AnalysisRun, name: str, *parts: Hashable) -> str:
    # the finish time too: a run id reused (a restored database, SQLite's rowids) is not
    # the same run
    stamp = run.finished_at.isoformat() if run.finished_at else ""
    digest = hashlib.sha256(repr((VERSION, stamp, name, parts)).encode()).hexdigest()[:32]
    return f"pt:chart:run{run.pk}:{digest}"


def cached_chart(run: AnalysisRun, name: str, parts: tuple, build: Callable[[], T]) -> T:
    """The chart ``build()`` draws, from the cache when this run already drew it."""
    key = chart_key(run, name, *parts)
    found = cache.get(key)
    if found is None:
        found = build()
        cache.set(key, found, TIMEOUT)
    return found
